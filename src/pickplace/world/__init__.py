"""The world the robot works in: the scene's configuration and the contact record (the bottom floor).

Floors of the package, top to bottom (an import only goes down): ``cli`` → ``eval`` → ``task`` →
``grasping`` → ``motion`` → ``robot`` → ``world`` → ``errors``.
"""
