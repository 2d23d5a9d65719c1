import sys

from asvtwin.cli import main

sys.exit(main())
