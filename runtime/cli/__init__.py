"""The ``irl`` command line: every subcommand, the plot, the diagrams and the generated docs.
"""
