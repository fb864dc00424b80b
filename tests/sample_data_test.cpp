// sample_data_test: filled in by its owner.
