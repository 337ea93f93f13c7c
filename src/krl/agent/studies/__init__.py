"""The thesis's agent studies (Sections 4.2.8.1-4.2.8.3) on Optuna: the designs (``designs``), running
their trials in any number of processes on one storage (``runner``), and their tables and figures
(``report``). ``krl agent study NAME`` is the command; docs/studies.md the guide."""
