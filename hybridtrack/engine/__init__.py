"""The engine: the bank of R runs × M filters, the pipeline over it, the simulator.  No files, no Rerun."""
