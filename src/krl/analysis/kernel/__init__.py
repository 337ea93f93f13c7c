"""The kernel's figures (``krl kernel figures``; thesis Figs. 4.9-4.13 and the kernel half of Fig. 4.15):
:mod:`~krl.analysis.kernel.metrics`, :mod:`~krl.analysis.kernel.recording` (the kernel's inputs, the
expert re-recorded with a kernel's training settings), one module per figure
(:mod:`~krl.analysis.kernel.trajectories`, :mod:`~krl.analysis.kernel.command_sweep`,
:mod:`~krl.analysis.kernel.symmetry`, :mod:`~krl.analysis.kernel.walk_gait`,
:mod:`~krl.analysis.kernel.heights`, :mod:`~krl.analysis.kernel.velocity`), what they share
(:mod:`~krl.analysis.kernel.context`) and the driver
(:func:`~krl.analysis.kernel.driver.make_kernel_figures`)."""
