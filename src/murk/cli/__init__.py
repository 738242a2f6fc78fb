"""The ``murk`` command line: one module per command; each parses options and delegates to the library."""
