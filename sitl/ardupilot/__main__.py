import sys

from sitl.ardupilot.pod import main

sys.exit(main())
