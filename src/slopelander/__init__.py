"""slopelander: fast multirotor landing on steep slopes.

Parts (one sub-package each, see ``docs/architecture.md``):

- ``slopelander.model``: the planar landing model (pure physics, no I/O).
- ``slopelander.envelope``: landing maps, presets and the lookup table.
- ``slopelander.legs``: the leg-board protocol and driver.
- ``slopelander.controller``: the companion-side landing controller.
"""

__version__ = "0.1.0"
