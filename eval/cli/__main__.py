"""``python -m drillgym.eval.cli``: the same as the ``drillgym`` command."""

from drillgym.eval.cli import main

raise SystemExit(main())
