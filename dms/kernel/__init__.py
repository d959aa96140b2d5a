"""The kernel: what every package of dms may import, and which imports nothing above it.

Messages (the pydantic contract), the clocks, the error root, ids, key expressions,
activity names, expression arbitration and the ports. Nothing here imports anything of
``dms`` outside ``dms.kernel``, nor ``managers``, ``activities``, ``motivation``,
``memory``, ``agenda`` or ``sim`` (see docs/architecture.md; tests/test_architecture.py).
"""
