import sys

from bouncelab.cli import main

sys.exit(main())
