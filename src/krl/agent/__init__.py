"""The residual agent (thesis Sections 4.2.7-4.2.9): the kernel plus low-pass-filtered PPO foot residuals.

Its action path (:mod:`~krl.agent.residual`, :mod:`~krl.agent.controller`), its environments
(:mod:`~krl.agent.env`), PPO training (:mod:`~krl.agent.train`) and policy files (:mod:`~krl.agent.policy`).
"""
