"""``python -m jaxmotion.play RUN [RUN ...]``: the interactive viewer (``viz/play.py``)."""

import sys

from jaxmotion.viz.play import main

if __name__ == "__main__":
    sys.exit(main())
