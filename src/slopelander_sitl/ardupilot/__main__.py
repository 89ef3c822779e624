import sys

from slopelander_sitl.ardupilot.pod import main

sys.exit(main())
