"""Analysis figures and tables: ``krl.analysis.expert_plots`` makes the MPC expert's figures (``krl expert
plot``: thesis Figs. 4.8, A.2, A.3 and the MPC half of Fig. 4.15; ``docs/expert_analysis.md``)."""
