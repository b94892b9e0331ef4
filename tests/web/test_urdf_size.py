"""A URDF upload above the size limit is refused with a line naming the file and the
limit in bytes (as the page's label says: at most 1 MB), not a schema message."""

from __future__ import annotations


def test_oversize_urdf_names_the_file(client, workspace):
    from campaign.web.robots_api import MAX_URDF_BYTES

    text = "<robot/>" + " " * (MAX_URDF_BYTES + 100_000)
    r = client.post("/api/robots/urdf", json={"name": "big.urdf", "text": text})
    assert r.status_code == 400
    d = r.json()
    assert d == {"detail": f"big.urdf: {len(text)} bytes; at most {MAX_URDF_BYTES} bytes",
                 "field": "urdf"}
    assert not (workspace / "robots").exists() or not any((workspace / "robots").iterdir())
    # far above it: refused by the request schema before it is read
    huge = client.post("/api/robots/urdf", json={"name": "big.urdf",
                                                 "text": "x" * (4 * MAX_URDF_BYTES + 1)})
    assert huge.status_code == 422
