"""Opt-in (--run-slow, about 5 minutes): the error bars of the whole chain are calibrated.

Twelve fake KR240-2 campaigns with different lab seeds, each planned, acquired over
loopback with the real drivers and identified with the protocol's noise model: the
standardised errors z = (k - k_true) / se(k) must look standard normal. Observed on
the development machine: std(z) per joint 0.55-1.14 over two such runs, mean(z) within
+-0.5 (the wrench noise in the weights is conservative: 0.5 N per averaged reading).
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.estimate import analyze_table
from campaign.acquire.progress import QuietReporter
from campaign.acquire.session import AcquireOptions, acquire
from campaign.planning.planner import make_plan, write_plan
from campaign.protocol import load_protocol
from campaign.protocol_robot import protocol_robot
from campaign.run_format.reader import read_run
from campaign.run_noise import noise_from_protocol
from tests.acquire.conftest import PROTOCOL

TRUE_K = np.array([1409800, 400760, 935280, 360000, 370000, 380000], dtype=float)


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_standardised_errors_of_twelve_campaigns(tmp_path):
    text = PROTOCOL.read_text()
    assert "seed = 1\n" in text
    zs = []
    for seed in range(2, 14):
        path = tmp_path / f"p{seed}.toml"
        path.write_text(text.replace("seed = 1\n", f"seed = {seed}\n", 1))
        protocol = load_protocol(path)
        plan = tmp_path / f"plan{seed}"
        write_plan(make_plan(protocol), plan, figure=False)
        out = tmp_path / f"run{seed}"
        outcome = acquire(plan, out, None,
                          AcquireOptions(fake=True, assume_yes=True, time_scale=200.0),
                          QuietReporter(), say=lambda s: None)
        assert outcome.status == "complete", outcome.reason
        run_protocol = load_protocol(out / "protocol.toml")
        result = analyze_table(read_run(out).ok, protocol_robot(run_protocol),
                               noise=noise_from_protocol(run_protocol), validate=False)
        zs.append((result.k - TRUE_K) / result.se_k)
    z = np.array(zs)
    # pooled over the 72 values the sample std of z has a spread of about 0.08
    assert 0.75 < z.std() < 1.3, z
    # per joint, 12 draws: loose bounds (3.3 sigma of a sample std; 3 sigma of a mean)
    assert np.all((z.std(axis=0) > 0.4) & (z.std(axis=0) < 1.7)), z
    assert np.all(np.abs(z.mean(axis=0)) < 0.9), z
    # pooled: about 95 % of the 72 intervals cover the truth
    assert np.mean(np.abs(z) < 1.96) > 0.88
