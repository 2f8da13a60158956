"""Deployments of the service beyond one process (Ray Serve)."""
