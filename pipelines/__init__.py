"""The dragline command and end-to-end pipelines."""
