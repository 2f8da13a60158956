"""The HTTP layer of hybrid-planner (FastAPI). ``api.app.create_app`` builds the service."""

__all__ = []
