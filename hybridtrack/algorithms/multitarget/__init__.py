"""Many targets at once: unlabelled detections in scans, gating, association (GNN, JPDA, MHT), track management."""
