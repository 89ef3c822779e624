"""Other simulators built to the model's equations, to measure speed and agreement against.

Each peer imports its simulator only when asked for (``slopelander.peers.mujoco_drop`` needs
the optional ``peers`` extra: ``pip install 'slopelander[peers]'``).
"""
