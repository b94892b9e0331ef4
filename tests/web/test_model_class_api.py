"""The GUI's API with a model.toml carrying link compliance: ``POST /api/jobs/stiffness`` (the Use
view's numbers) gives the kernel's deflection and K_X to 1e-9, and the independent
computation of tests/use/test_link_compliance_kernel.py (Pinocchio, written from the
equations) agrees to 1e-9."""

from __future__ import annotations

import shutil

import numpy as np

from analysis.kinetostatics.link_compliance import (
    deflection_with_links,
    links_of,
    stiffness_with_links,
)
from analysis.model.robot_files import load_robot_file
from tests.use.test_compensator_law import _independent as _independent_law
from tests.use.test_compensator_law import _law_k, _q
from tests.use.test_compensator_law import _model_file as _law_model_file
from tests.use.test_link_compliance_kernel import Q, W, _independent, _model_file


def test_stiffness_api_uses_the_model_files_links(client, workspace, tmp_path):
    src = _model_file(tmp_path)
    shutil.copy(src, workspace / "model.toml")
    robot = load_robot_file(src)
    k = robot.nominal_stiffness
    r = client.post("/api/jobs/stiffness", json={"robot": "model.toml", "q_rad": Q.tolist(),
                                            "wrench_N_Nm": W.tolist()})
    assert r.status_code == 200, r.text
    doc = r.json()
    got = np.array(doc["deflection_m_rad"])
    kernel = deflection_with_links(robot, Q, k, W, links_of(robot))[0]
    ref = _independent(robot, Q, k, W)
    scale = np.abs(ref).max()
    assert np.abs(got - kernel).max() <= 1e-9 * scale
    assert np.abs(got - ref).max() <= 1e-9 * scale
    K = stiffness_with_links(robot, Q, k, W, links_of(robot))[0]
    assert np.abs(np.array(doc["K_X"]) - K).max() <= 1e-9 * np.abs(K).max()
    # the built-in robot file (joint springs only) answers differently
    r0 = client.post("/api/jobs/stiffness", json={"robot": "robot.toml", "q_rad": Q.tolist(),
                                             "wrench_N_Nm": W.tolist()})
    assert np.abs(np.array(r0.json()["deflection_m_rad"]) - got).max() > 0.01 * scale


def test_stiffness_api_uses_the_compensator_law(client, workspace, tmp_path):
    """The Use view's numbers with the axis-2 compensator law: the equations' deflection
    (k2(q2) from the law, tests/use/test_compensator_law.py) to 1e-9, as the job's."""
    from analysis.kinetostatics.compensator_law import compensator_law_of
    from campaign.jobs.stiffness import StiffnessOptions, run

    src = _law_model_file(tmp_path)
    shutil.copy(src, workspace / "model.toml")
    robot = load_robot_file(src)
    law = compensator_law_of(robot)
    for q2 in (5.0, 100.0):
        q = _q(q2)
        r = client.post("/api/jobs/stiffness", json={"robot": "model.toml",
                                                     "q_rad": q.tolist(),
                                                     "wrench_N_Nm": W.tolist()})
        assert r.status_code == 200, r.text
        doc = r.json()
        got = np.array(doc["deflection_m_rad"])
        ref = _independent_law(robot, q, _law_k(robot.nominal_stiffness.copy(), q, law.c1,
                                                law.c2), W)
        assert np.abs(got - ref).max() <= 1e-9 * np.abs(ref).max()
        job = run(StiffnessOptions(robot=str(src), q_rad=q, wrench_N_Nm=W))
        assert np.abs(got - np.array(job.deflection_m_rad)).max() <= 1e-9 * np.abs(ref).max()
        assert "compensator law" in doc["compensator"]["law"]
