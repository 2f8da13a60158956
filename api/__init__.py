"""The HTTP layer of hybrid-planner (FastAPI). ``planner_api.app.create_app`` builds the service."""

__all__ = []
