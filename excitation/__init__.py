"""Excitation signals for identification (``servoid.excitation``).

Bounded, persistently exciting inputs that meet the paper's Remark 2 and
respect a servo's limits; pure, seeded and resumable generators.
"""
