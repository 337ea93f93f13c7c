"""A stand-in ``krl`` for the tests of the pipeline scripts under examples/: a shell script on PATH that
logs its arguments (and does what each test's script text says)."""

from __future__ import annotations

import os
from pathlib import Path


def stand_in_environment(folder: Path, script: str, **variables: str) -> dict[str, str]:
    """The environment in which ``krl`` is ``script`` (written to ``folder/bin/krl``), logging to
    ``folder/krl.log`` (``LOG``), with ``variables`` set."""
    bin_dir = folder / "bin"
    bin_dir.mkdir()
    (bin_dir / "krl").write_text(script)
    (bin_dir / "krl").chmod(0o755)
    return (
        os.environ | {"PATH": f"{bin_dir}:{os.environ['PATH']}", "LOG": str(folder / "krl.log")} | variables
    )
