"""``krl reproduce``: every table and figure of ``docs/results`` and ``docs/figures`` from nothing.

The pipeline is a table of ``krl`` commands in order (:func:`pipeline`: expert data -> kernels -> kernel
studies and figures -> both agents from each training seed -> evaluation -> report -> krl's agents), each
with the wall time it took on the 2-core development machine (``docs/reproduce.md``); :func:`plan` fills
in the folders, the mode and the seeds, giving one :class:`Step` per row. A finished step leaves a marker
(``RUNS/.reproduce/<step>.json``, holding its command), so running ``krl reproduce`` again skips what is
done and resumes the step that was interrupted (every long command it runs resumes by itself). With
``--quick`` every step is cut down (tens of waypoints, a few epochs, a short agent training, one push per
magnitude) into ``RUNS/quick``, whose documents go to ``RUNS/quick/docs``: the same pipeline in about 75
minutes here, never touching ``docs/``.
"""

from krl.apps.reproduce.run import describe, is_done, plan, reproduce
from krl.apps.reproduce.table import Step

__all__ = ["Step", "describe", "is_done", "plan", "reproduce"]
