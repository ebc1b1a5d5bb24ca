"""Where model and measurement disagree, and which physical effect is missing.

``residuals``       the residual by regime, and ``resid``-style whiteness tests
``diagnose``        the discrepancy workflow: fit each candidate effect, keep the one that pays
``hidden_effects``  records with a known effect hidden in them: the workflow's known-truth test data
"""
