"""reconstruct stage of dragline."""
