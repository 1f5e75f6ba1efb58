"""Writing results: atomic file writes, ParaView particle series, CSV metrics."""
