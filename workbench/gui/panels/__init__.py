"""Job panels (exposure sweep, experiments): run core jobs in the background and chart results."""
