"""``python -m planner_cli``: the ``planner`` command line."""

from planner_cli.app import app

app(prog_name="planner")
