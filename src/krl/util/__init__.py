"""The bottom layer: rates and periods (:mod:`~krl.util.timing`), atomic result writers
(:mod:`~krl.util.output`), progress bars, the process pool, the Optuna storage of searches and studies and
the thesis's protocol constants. Imports no other krl package.
"""
