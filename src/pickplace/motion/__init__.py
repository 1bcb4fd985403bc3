"""Moving the arm: collision checking, RRT* planning, TOPP-RA time scaling, impedance control loops."""
