"""Expert data for the kernel (thesis Section 4.2.6.2): collection and the versioned dataset schema.

- :mod:`krl.data.collect`: the MPC expert walks to random targets and every 200 Hz control step becomes
  one row; the data is written as one Parquet part file per episode plus ``manifest.json``, resumably
  (``krl collect``).
- :mod:`krl.data.storage`: the dataset directory on disk: atomic, durable part and manifest writes, the
  writer's lock, and checking an existing dataset before a collection resumes it.
- :mod:`krl.data.schema`: the columns (:data:`FIELDS`, schema version :data:`SCHEMA_VERSION`) and
  :func:`load_dataset`, which checks every file and gives numpy arrays by field name.

``docs/data.md`` describes the layout, the modes and every choice where the thesis is ambiguous.
"""

from krl.data.collect import (
    MODES,
    CollectConfig,
    CollectSummary,
    EpisodeStats,
    collect_dataset,
    collect_episode,
)
from krl.data.schema import (
    FIELD_NAMES,
    FIELDS,
    SCHEMA_VERSION,
    Dataset,
    DatasetError,
    FieldSpec,
    field_spec,
    load_dataset,
)
from krl.data.storage import SettingsMismatchError

__all__ = [
    "FIELDS",
    "FIELD_NAMES",
    "MODES",
    "SCHEMA_VERSION",
    "CollectConfig",
    "CollectSummary",
    "Dataset",
    "DatasetError",
    "EpisodeStats",
    "FieldSpec",
    "SettingsMismatchError",
    "collect_dataset",
    "collect_episode",
    "field_spec",
    "load_dataset",
]
