"""A model.toml whose covariance gives no stiffness interval is refused by every reader
(``stiffness``, ``robots``: one line, exit 2), not turned into a deflection interval of
+-1.5e4 mm around 9.4 mm (issue 29, item 7)."""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri

from analysis.model.robot_files import load_robot_file
from campaign.cli import main

Q = "15,50,-195,30,40,20"


def _scaled(identified, tmp_path, factor: float):
    """model.toml with its covariance multiplied by ``factor`` (as a hand edit would)."""
    import tomllib

    import tomli_w

    doc = tomllib.loads((identified / "model.toml").read_text())
    ident = doc["identification"]
    ident["covariance"] = [[v * float(factor) for v in row] for row in ident["covariance"]]
    out = tmp_path / f"model-x{factor:g}.toml"
    out.write_text(tomli_w.dumps(doc))
    return out


def test_identified_model_is_far_from_the_bound(identified):
    model = load_robot_file(identified / "model.toml")
    x = 1.0 / model.nominal_stiffness
    rel = np.sqrt(np.diag(model.compliance_covariance)) / x
    z = ndtri(0.975)
    assert np.all(z * rel < 0.2), rel  # a campaign's k to a few per cent: well inside


def test_covariance_times_1e12_refused_by_stiffness_and_robots(identified, tmp_path,
                                                                 capsys):
    model = load_robot_file(identified / "model.toml")
    rel = np.sqrt(np.diag(model.compliance_covariance)) * model.nominal_stiffness
    # the factor at which the widest joint's 95 % interval just reaches zero
    edge = (1.0 / (ndtri(0.975) * rel.max())) ** 2
    assert load_robot_file(_scaled(identified, tmp_path, edge * 0.99)) is not None
    for factor in (edge * 1.01, 1e12):
        path = _scaled(identified, tmp_path, factor)
        for args in (["stiffness", "--robot", str(path), "--q", Q],
                     ["robots", str(path)]):
            capsys.readouterr()
            assert main(args) == 2, (factor, args)
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and "Traceback" not in err[0], err
            joint = 1 + int(np.flatnonzero(ndtri(0.975) * rel * np.sqrt(factor) >= 1)[0])
            assert f"joint {joint}: the compliance's 95% interval reaches zero" in err[0], err
