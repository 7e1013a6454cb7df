"""The reproduction of the paper's experiments, in three steps that read on their own.

`experiments` runs the samples through both matchers, `findings` reads the numbers
from the runs, `figures` draws them and `document` writes the README section;
``scripts/reproduce_paper.py`` is the command line.
"""
