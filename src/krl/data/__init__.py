"""Expert data for the kernel (thesis Section 4.2.6.2): collection and the versioned dataset schema.

- :mod:`krl.data.schema`: the columns (``FIELDS``, schema version ``SCHEMA_VERSION``) and their Arrow
  encoding and content hashes.
- :mod:`krl.data.columns`: the columns computed from a simulator state, the one builder of a kernel's input
  row (collection, the kernel controller and the residual agent all use it).
- :mod:`krl.data.storage`: the writer: atomic, durable part and manifest writes, the writer's lock, and
  checking an existing dataset before a collection resumes it.
- :mod:`krl.data.reader`: ``load_dataset``, which checks every file and gives numpy arrays by field name.
- :mod:`krl.data.collect`: the MPC expert walks to random targets and every 200 Hz control step becomes
  one row, collected resumably (``krl collect``).

Importing this package imports none of them, so a reader of datasets does not pull in the MPC expert.
``docs/data.md`` describes the layout, the modes and every choice where the thesis is ambiguous.
"""
