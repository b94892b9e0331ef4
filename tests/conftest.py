"""Shared pytest options: hardware addresses, the opt-in slow marker, loopback only."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from drivers.loopback_guard import ENV as LOOPBACK_ONLY

#: environment variables a pytest-xdist worker finds set to its own values (COLUMNS=80,
#: LINES=24), which the commands under test read as the terminal's width
WORKER_ENV = ("COLUMNS", "LINES")


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node) -> None:
    """pytest-xdist, on the controller: hand each worker this process's :data:`WORKER_ENV`."""
    node.workerinput["stiffness_worker_env"] = {k: os.environ.get(k) for k in WORKER_ENV}


def pytest_configure(config: pytest.Config) -> None:
    # A pytest-xdist worker runs the tests in the environment of the command that started
    # pytest: without this a worker's COLUMNS=80 made the CLI wrap its messages there
    # and not in one pytest process (tests that need a width set it themselves).
    for key, value in getattr(config, "workerinput", {}).get("stiffness_worker_env",
                                                             {}).items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value
    # Ctrl-C is Python's KeyboardInterrupt here and in every process the tests start,
    # however the run was launched: a shell's background job (`pytest &`, nohup, some CI
    # runners) inherits SIGINT ignored, Python then leaves it ignored, and so do the
    # processes it starts, so the tests that press Ctrl-C (the acquisition's abort,
    # the live panel, the GUI's abort) saw their run complete instead.
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    # Nothing leaves loopback: every driver this run (and every process it starts) builds
    # refuses a device off this machine, unless a real device's address was given.
    if not any(config.getoption(o) for o in ("--ft-url", "--tracker-url", "--robot-url")):
        os.environ[LOOPBACK_ONLY] = "1"


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("stiffness-campaign")
    group.addoption("--ft-url", default=None, help="Address of a real force/torque sensor.")
    group.addoption("--tracker-url", default=None, help="Address of a real laser tracker.")
    group.addoption("--robot-url", default=None, help="Address of a real robot controller.")
    group.addoption("--run-slow", action="store_true", default=False,
                    help="Run long soak and fuzzing tests (marker 'slow').")


#: the heavy end-to-end tests besides every browser test (marker ``e2e``; the fast lane
#: ``pytest -m "not e2e"`` leaves them out, the README's test command runs them): whole
#: campaigns in processes of their own, seeded Monte-Carlo studies of whole campaigns,
#: the API fuzzer, chromium renderings. Each took >= 8 s on 2 cores (docs/testing.md).
E2E = (
    "tests/studies/test_robust_coverage.py", "tests/studies/test_linear_bias.py",
    "tests/studies/test_holdout_check.py", "tests/studies/test_worst_joint.py",
    "tests/studies/test_zscore_study.py", "tests/studies/test_z1_coverage.py",
    "tests/use/test_compensation.py::test_fake_lab_verification_on_the_demo",
    "tests/acquire/test_reproducible_fake.py", "tests/acquire/test_full_campaign.py",
    "tests/acquire/test_abb_fanuc_campaigns.py", "tests/acquire/test_ur10e_campaign.py",
    "tests/jobs/test_demo.py", "tests/web/test_fuzz.py",
    "tests/report/test_signed_report.py::test_html_in_chromium_first_screen_and_width",
    "tests/report/test_analyze_imports.py",
    "tests/identification/test_golden.py::test_other_processors_kernels_pass",
    "tests/web/test_acquire_view.py::test_start_state_stream_abort_resume",
    "tests/web/test_jobs_queue.py", "tests/web/test_plan_workspace_robot.py",
    "tests/acquire/test_resume.py::test_kill9_at_seeded_moments_then_resume",
    "tests/use/test_brand_programs.py::test_place_programs_round_trip",
    "tests/report/test_signed_report.py",
    "tests/drivers/test_realistic_world.py::test_preloaded_shop_run_records_the_reference_wrench",
    # whole acquisitions in processes of their own (each >= 10 s at load 8, -n 2)
    "tests/drivers/test_realistic_world.py::test_shop_protocol_through_the_fakes",
    "tests/drivers/test_lab_loopback.py",
    "tests/acquire/test_resume.py::test_ctrl_c_stops_unloads_records_and_resumes",
    "tests/acquire/test_resume.py::test_resume_of_a_complete_run_measures_nothing",
    "tests/jobs/test_acquire.py::test_acquire_same_tests_csv_from_cli_and_api",
    "tests/jobs/test_acquire.py::test_job_in_its_own_process_aborts_by_signal_like_ctrl_c",
    # the fast lane's slowest tests (each 11-22 s at load 5, -n 2): model-class fits of
    # whole simulated campaigns, maps and placement in processes of their own, a wheel
    # built and installed, an acquisition through every web route
    "tests/identification/test_model_classes_cli.py::test_auto_on_compliant_links_chooses_links_and_reports_candidates",
    "tests/identification/test_model_classes.py::test_compensator_with_lost_motion_finds_joint_2s_flanks",
    "tests/identification/test_model_classes.py::test_clean_lab_keeps_joints_with_todays_k",
    "tests/identification/test_design_size.py::test_auto_sets_aside_links_on_the_saturated_five_test_plan",
    "tests/identification/test_design_size.py::test_auto_chooses_links_on_the_planners_raised_design",
    "tests/web/test_plan_save.py::test_an_existing_name_is_refused_unless_replacing_is_asked",
    "tests/web/test_api_safety.py::test_one_acquisition_per_robot_through_every_route",
    "tests/project/test_wheel_protocols.py",
    "tests/cli/test_cli.py::test_maps_on_robot_without_length_computes_it",
    "tests/cli/test_cli_conventions.py::test_maps_json_and_no_silent_overwrite",
    "tests/jobs/test_maps.py::test_maps_same_files_from_cli_and_api",
    "tests/placement/test_place_scratch.py::test_local_cluster_leaves_no_scratch_space",
    # simulated acquisitions with faults, aborts and resumes (3-6 s each at rest, -n 2)
    "tests/acquire/test_faults.py", "tests/acquire/test_damaged_inputs.py",
    "tests/acquire/test_abort_records.py::test_fault_while_loaded_records_every_removal_then_resume_marks_sessions",
    "tests/acquire/test_abort_records.py::test_disk_full_mid_run_stops_safely_and_the_run_resumes",
    "tests/acquire/test_tool_offset.py::test_fake_campaign_with_tool_offset",
    "tests/acquire/test_cut_tests_csv_resume.py::test_analyze_names_the_resume_that_repairs_a_cut_line",
    "tests/drivers/test_realistic_world.py::test_preloaded_readings_are_the_applied_wrenches",
)
#: session fixtures that run whole campaigns: a test using one is end-to-end
CAMPAIGN_FIXTURES = ("demo_runs",)
#: test files that run on one pytest-xdist worker, one after the other (the README's
#: ``--dist loadfile`` otherwise gives each file to whichever worker is free): the files
#: sharing a whole-campaign session fixture, which is then made once, not once per worker.
#: A test that cannot run beside another joins a group here (pytest-xdist's own
#: ``xdist_group`` mark does not group with pytest 9.2: pytest-xdist issue 1386).
SAME_WORKER = {
    "demo_runs": ("tests/ledger/test_fleet_study.py", "tests/ledger/test_fleet_view.py",
                  "tests/ledger/test_ledger_analyze.py", "tests/ledger/test_ledger_history.py",
                  "tests/ledger/test_ledger_reliability.py"),
}


def _e2e(item: pytest.Item) -> bool:
    """Whether ``item`` is an end-to-end test: it opens a browser (the ``browser``
    fixture, directly or through a page), uses whole campaigns (:data:`CAMPAIGN_FIXTURES`),
    or :data:`E2E` names its file or function."""
    if {"browser", *CAMPAIGN_FIXTURES} & set(getattr(item, "fixturenames", ())):
        return True
    node = item.nodeid.split("[")[0]
    return any(node == e or node.startswith(e + "::") for e in E2E)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """pytest-xdist's ``--dist loadfile``, with the files of each :data:`SAME_WORKER` group
    as one unit of work; None (xdist's own choice) for the other ``--dist`` modes."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    group_of = {path: name for name, paths in SAME_WORKER.items() for path in paths}

    class GroupedFiles(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return "group:" + group_of[path] if path in group_of else path

    return GroupedFiles(config, log)


@pytest.hookimpl(tryfirst=True)  # first: the -m selection reads the e2e marks
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if _e2e(item):
            item.add_marker(pytest.mark.e2e)
    if config.getoption("--run-slow"):
        return
    skip = pytest.mark.skip(reason="slow: opt in with --run-slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def analyses(tmp_path_factory) -> tuple[Path, Path]:
    """Two analysis directories (results.json, model.toml) of simulated KR240-2 campaigns,
    B measured with its joint 2 10 % stiffer (written by ``campaign analyze`` from CSVs),
    made once per session for the job, Use-view and API tests: read only (copy them)."""
    from tests.use._campaigns import TRUE_K
    from tests.use.conftest import analyze

    tmp = tmp_path_factory.mktemp("analyses")
    k_b = TRUE_K.copy()
    k_b[1] *= 1.10
    return analyze(tmp, "A", seed=3), analyze(tmp, "B", seed=4, k=k_b)


@pytest.fixture(scope="session")
def browser():
    """One headless Chromium (Debian's ``chromium``, through Playwright) for the whole
    session (the web and ledger tests): a launch costs seconds on a loaded machine; the
    tests' pages each get their own context (no cookie or storage shared)."""
    from tests.web.conftest import CHROMIUM

    if not CHROMIUM.exists():
        pytest.skip("browser tests need the Debian package chromium (/usr/bin/chromium)")
    sync_api = pytest.importorskip("playwright.sync_api",
                                   reason="browser tests need pip install playwright")
    p = sync_api.sync_playwright().start()
    try:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
        yield b
        b.close()
    finally:
        p.stop()
