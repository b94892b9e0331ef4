"""The web face: a FastAPI application over the jobs."""
