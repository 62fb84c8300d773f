"""Small services every stage uses: the per-user cache directory, atomic file writes, bundled data."""
