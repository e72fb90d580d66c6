"""One module per ``beambench`` subcommand: ``add_arguments`` and ``run``; its one-line
help is in :data:`pipelines.cli.COMMANDS`, which imports the module only when its
command runs."""
