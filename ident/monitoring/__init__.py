"""Following a servo's backlash while it works: the wear estimator and the alarm rule.

``wear_estimator``  the MRGIA with random-walk parameters on normalised signals, with uncertainty and a running fit
``alarms``          when a monitored quantity has left its bounds (margin, persistence, hysteresis)
``loop_wear``       a play inside the loop: the whole loop refitted once, then the play alone on short windows, a CUSUM on it
``play_fit``        the play alone fitted on a short window, every other servo-loop parameter held (a grid search)
``cusum``           Page's CUSUM with its reference at a bound, its threshold from a false-alarm rate
"""
