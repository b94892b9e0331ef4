"""The placement estimate's view of the machine: the other runnable processes from the
kernel's run queue (campaign.use.place_cluster.other_runnable), read from a file in the
format of /proc/loadavg."""

from __future__ import annotations

from campaign.use.place_cluster import other_runnable


def test_run_queue_less_this_process(tmp_path, monkeypatch):
    monkeypatch.setattr("campaign.use.place_cluster.QUEUE_INTERVAL", 0.0)
    f = tmp_path / "loadavg"
    f.write_text("7.50 6.00 5.00 4/812 12345\n")  # a 1-minute average of 7.5, 4 runnable now
    others, how = other_runnable(str(f))
    assert others == 3.0  # 4 runnable, one of them this process; not the stale 7.5
    assert "3 other runnable" in how
    f.write_text("2.04 5.03 6.95 1/700 1\n")  # idle now, a busy minute behind it
    assert other_runnable(str(f))[0] == 0.0


def test_without_the_file_the_load_average(tmp_path):
    others, how = other_runnable(str(tmp_path / "absent"))
    assert others >= 0.0 and "load average" in how
