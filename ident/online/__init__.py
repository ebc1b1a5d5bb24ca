"""Estimators that step one sample at a time, in constant memory.

``mrgia``          the paper's MRGIA (eqs 17-42): :class:`~servoid.ident.online.mrgia.MRGIA` and its batch twin
``_mrgia_kernel``  its compiled step on a flat state vector, each line citing its equation
"""
