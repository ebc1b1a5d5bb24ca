"""Following a servo's backlash while it works: the wear estimator and the alarm rule.

``wear_estimator``  the MRGIA with random-walk parameters on normalised signals, with uncertainty and a running fit
``alarms``          when a monitored quantity has left its bounds (margin, persistence, hysteresis)
``loop_wear``       a play inside the loop: the servo-loop model's window refit with the alarm rule on its play
"""
