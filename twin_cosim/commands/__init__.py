"""The commands of ``twin``, one module each: its arguments (``add_arguments``) and ``run``.

A command module imports only the standard library and light registries at start, so that
``twin --help`` answers at once; its ``run`` imports the library it calls (numpy, pandas, fmpy,
numba, matplotlib) when it runs.
"""
