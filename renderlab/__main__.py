import sys

from renderlab.cli import main

sys.exit(main())
