"""Estimators that step one sample at a time, in constant memory.

``estimator``      the ``Estimator`` protocol every online estimator satisfies (update, skip, warm_up, current)
``mrgia``          the paper's MRGIA (eqs 17-42): :class:`~servoid.ident.online.mrgia.MRGIA` and its batch twin
``_mrgia_kernel``  its compiled step on a flat state vector, each line citing its equation
``decimate``       the MRGIA on a decimated stream, at a rate where its convergence condition holds
``window``         the servo-loop model online: a moving-window refit, warm-started, on a worker thread

A new online estimator (one that decimates, a probe) is a module here that satisfies ``Estimator``.
"""
