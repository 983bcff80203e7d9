"""Use cases: what a lab user asks the program to do, in one place for every front end.

Each module here is one use case (identify, design with its 2x2 logic, calibrate,
experiment, exercise, grade, figures): functions with typed inputs and results that
the CLI command (commands/) and the screen (ui/) both call, so their defaults and
their answers cannot differ. A use case orchestrates the core and the files; it
parses no arguments, prints nothing and draws nothing.
"""
