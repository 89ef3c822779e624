"""The firmware on a host, under MicroPython: ``micropython host_main.py WIRE_DIR --fd N ...``.

``WIRE_DIR`` is where the shared protocol module ``wire.py`` lives (``src/slopelander/legs`` in
a checkout; on a board it sits beside ``main.py``). ``slopelander_sitl.legboard`` starts this with the
pseudo-terminal's descriptor and talks to it over stdin/stdout (``legfw.host.main``).
"""

import sys

sys.path.append(sys.argv[1])

from legfw.host import main

main(sys.argv[2:])
