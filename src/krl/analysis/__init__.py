"""Analysis figures and tables, one subpackage per family: :mod:`krl.analysis.expert` (``krl expert plot``:
thesis Figs. 4.8, A.2, A.3 and the MPC half of Fig. 4.15; ``docs/expert_analysis.md``) and
:mod:`krl.analysis.kernel` (``krl kernel figures``: Figs. 4.9-4.13 and the kernel half of Fig. 4.15;
``docs/kernel_figures.md``). What both share: :mod:`krl.analysis.common` (the velocity sweep, line fits,
writing a figure's files) and :mod:`krl.analysis.panels` (drawing helpers)."""
