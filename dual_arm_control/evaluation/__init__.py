"""Episode evaluation from simulator ground truth: trajectory logs, metrics, plots."""
