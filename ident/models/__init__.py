"""What a servo is: the model structures, the physical effects that extend them, and their simulation.

``pseudo_wiener``  the paper's model: a linear block followed by an output backlash (eqs 1-11)
``kernels``        the compiled backlash operator, simulation loop and stability test
``simulate``       free-run simulation with measurement noise
``plant``          the model stepped one sample at a time (what simulated servos run)
``wear``           a plant whose dead zones change with its age (gear wear, a gear swap)
``effects``        the library of candidate physical effects (friction, saturation, ...)
``extended``       the pseudo-Wiener model extended by effects, its simulation and fit
``servo_loop``     the grey-box servo loop: the play outside or inside the position loop (``structure_names``)
"""
