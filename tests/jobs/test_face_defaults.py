"""The GUI starts where the command line starts: every default of a GUI request (the
pydantic models of the API, read from its OpenAPI document, which the page fills its fields
from) equals the default of the ``campaign`` option that sets the same thing (read from the
typer command)."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("fastapi", reason="fastapi is not installed (pip install fastapi)")


def _cli_defaults(command: str) -> dict[str, object]:
    """{option name (``--method``): default} of ``campaign COMMAND`` (enums as their value)."""
    from campaign.cli.app import LAZY_COMMANDS, load_command

    cmd = load_command(command, LAZY_COMMANDS[command][0])
    out = {}
    for param in cmd.params:
        for opt in param.opts:
            default = param.default
            out[opt] = getattr(default, "value", default)
    return out


@pytest.fixture(scope="module")
def schemas(tmp_path_factory) -> dict:
    """The request schemas of the GUI's API (``components.schemas`` of /openapi.json)."""
    from campaign.web.app import create_app

    app = create_app(Path(tmp_path_factory.mktemp("ws")), "tok-0123456789abcdef")
    return app.openapi()["components"]["schemas"]


def _default(schemas: dict, model: str, field: str):
    return schemas[model]["properties"][field]["default"]


# (GUI request model, its field, CLI command, its option): the same setting
SAME = [
    ("AnalyzeOptions", "method", "analyze", "--method"),     # Plan & Analyze: Analyze
    ("AnalyzeOptions", "robust", "analyze", "--robust"),
    ("AnalyzeOptions", "covariance", "analyze", "--covariance"),
    ("AnalyzeOptions", "trials", "analyze", "--trials"),
    ("PlanRequest", "candidates", "plan", "--candidates"),   # Plan & Analyze: Plan
    ("PlanRequest", "seed", "plan", "--seed"),
    ("PlanRequest", "strategy", "plan", "--strategy"),
    ("SensitivityRequest", "method", "robustness", "--method"),  # the explorer = Fig. 7
    ("RobustnessOptions", "method", "robustness", "--method"),
    ("RobustnessOptions", "trials", "robustness", "--trials"),
]


@pytest.mark.parametrize("model,field,command,option", SAME,
                         ids=[f"{m}.{f}" for m, f, _, _ in SAME])
def test_a_gui_default_is_the_command_lines(schemas, model, field, command, option):
    assert _default(schemas, model, field) == _cli_defaults(command)[option]


def test_the_defaults_named_by_the_review():
    """The three that differed: Analyze ols (CLI exact), Plan 2,000 candidates (CLI
    10,000), the sensitivity explorer ols (robustness exact)."""
    from analysis.choices import DEFAULT_METHOD

    assert DEFAULT_METHOD == "exact"
    assert _cli_defaults("analyze")["--method"] == DEFAULT_METHOD
    assert _cli_defaults("plan")["--candidates"] == 10_000
    assert _cli_defaults("robustness")["--method"] == DEFAULT_METHOD


def test_the_page_takes_its_defaults_from_the_api():
    """No default typed into the page for these fields: they come from the schemas."""
    html = (Path(__file__).parents[2] / "campaign" / "web" / "static" / "index.html").read_text()
    assert '<select id="an-method"></select>' in html and '<select id="method" ' in html
    assert 'id="plan-candidates" type="number" min="10">' in html
