"""Fits over a whole record, after the online run: output-error refinement and its starts.

``refine``   output-error least squares of the pseudo-Wiener model, with standard errors; the ARX start
``_oefit``   the least-squares machinery shared with the extended model's fit
``loop_fit`` the servo-loop model with the play outside and inside the loop, chosen by validation
"""
