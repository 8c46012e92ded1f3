"""capture stage of dragline."""
