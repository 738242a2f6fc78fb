"""Networks (Joint-ID, lite; the comparison baselines UDAformer and URSCT-SESR).

Each network has its own ``build_*`` function; methods are built by name through the one registry,
:mod:`murk.enhance.restorer`.
"""
