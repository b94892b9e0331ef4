"""The report's operator line says when the name recorded is only the OS login."""

from __future__ import annotations

from campaign.jobs.analyze_input import operator_text


def test_a_login_name_is_labelled_as_such():
    meta = {"operator": "root", "operator_source": "OS user (no --operator given)"}
    assert operator_text(meta) == "root (OS user (no --operator given))"


def test_a_name_given_with_operator_is_shown_alone():
    assert operator_text({"operator": "A. Dumas", "operator_source": "--operator"}) \
        == "A. Dumas"


def test_older_runs_without_a_source_and_missing_names():
    assert operator_text({"operator": "test bench"}) == "test bench"
    assert operator_text({}) == "-"
