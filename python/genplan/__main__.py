import sys

from genplan.cli import main

sys.exit(main())
