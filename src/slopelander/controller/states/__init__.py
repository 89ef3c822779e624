"""The landing sequence, one phase per module; :mod:`slopelander.controller.machine` runs them."""
