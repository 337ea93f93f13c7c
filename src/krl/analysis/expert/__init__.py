"""The MPC expert's figures (``krl expert plot``; thesis Figs. 4.8, A.2, A.3 and the MPC half of Fig. 4.15):
:mod:`~krl.analysis.expert.metrics` (the CoM metric), :mod:`~krl.analysis.expert.runs` (one job per
condition, run in worker processes), :mod:`~krl.analysis.expert.plan` (the conditions of each figure),
:mod:`~krl.analysis.expert.com` and :mod:`~krl.analysis.expert.velocity` (tables and drawings), and
:mod:`~krl.analysis.expert.driver` (:func:`~krl.analysis.expert.driver.make_figures`)."""
