"""skyfuse tracking library: pure computation over NumPy arrays, no I/O.

Sub-packages: ``frames`` (geodesy, system plane, plot conversion), ``models`` (motion
models), ``filters`` (batched KF/EKF/IMM), ``association`` (gating, GNN, auction),
``tracker`` (existence-based multi-target trackers), ``sim`` (scenario simulator),
``metrics`` (evaluation measures).
"""
