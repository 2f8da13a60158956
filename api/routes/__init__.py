"""One router per resource."""

__all__ = []
