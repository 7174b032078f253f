"""pytest plugin (entry point ``pytest11``) exposing hybridtrack's contract checks."""
