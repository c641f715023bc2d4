"""The commands of ``twin``, grouped by concept: each command is its arguments
(``add_<command>``) and its ``run_<command>``, the commands of one concept in one module
(``axis_tests``: step, kv, friction; ``frequency``: bode, calibrate, autotune; ...).

A command module imports only the standard library and light registries at start, so that
``twin --help`` answers at once; a command's run imports the library it calls (numpy, pandas,
fmpy, numba, matplotlib) when it runs.
"""
