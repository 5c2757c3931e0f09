"""The ``skyfuse`` command line: entry point, configuration loading, progress and one
module per command."""
