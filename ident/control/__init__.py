"""Compensating the backlash: the inverse, the feedforward, and the closed loop that proves them.

``compensate``          the smoothed backlash inverse and its default band
``feedforward``         the command that makes ``x`` follow a planned path through the linear block
``tracking``            reference tracking control of a backlash servo, with and without the inverse
``references``          reference paths for those tracking tests
``compensation_study``  proof by simulation: does the inverse help, and how wrong may the model be?
``reversal_lead``       the compensator for a play inside the position loop: a set-point lead at reversals
"""
