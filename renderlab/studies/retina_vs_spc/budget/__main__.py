"""``python -m renderlab.studies.retina_vs_spc.budget run|report`` (:mod:`.runner`)."""

import sys

from renderlab.studies.retina_vs_spc.budget.runner import main

sys.exit(main())
