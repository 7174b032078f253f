"""Contract checks for hybridtrack components (filled in by the testing module)."""
