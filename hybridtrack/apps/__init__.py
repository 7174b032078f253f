"""Applications on the algorithms: tracking real files, mode labels, the experiment runner, reporting."""
