// cli_test: filled in by its owner.
