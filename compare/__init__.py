"""compare stage of dragline."""
