"""Built-in detectors plugins: each public module registers its own components through its hook and is an entry point."""
