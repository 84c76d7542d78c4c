"""``python -m jaxmotion.plot RUN [RUN ...]``: learning curves (``viz/plot.py``)."""

import sys

from jaxmotion.viz.plot import main

if __name__ == "__main__":
    sys.exit(main())
