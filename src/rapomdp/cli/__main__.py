"""``python -m rapomdp.cli``: the ``rapomdp`` console script."""

from rapomdp.cli import main

main()
