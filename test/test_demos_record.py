"""`skillgen demos record` end to end from a pseudo-terminal (issue 24): the teleop's status line shows,
`q` runs the task's success check and prints the verdict, and the failed demo leaves the recordings
folder (sim_driver + recorder + teleop, real processes over DDS)."""
from __future__ import annotations

import os
import pty
import subprocess
import sys
import termios

from conftest import node_env, wait_for


def test_record_shows_status_and_judges_the_demo_on_q(ros_domain, tmp_path):
    out = tmp_path / "recordings"
    log = tmp_path / "record.log"
    master, slave = pty.openpty()
    with open(log, "w") as f:
        proc = subprocess.Popen([sys.executable, "-m", "skillgen_ros.cli.main", "demos", "record", "--task", "Square",
                                 "--out", str(out)], stdin=slave, stdout=f, stderr=subprocess.STDOUT,
                                env=node_env(ros_domain), cwd=tmp_path, text=True)
    os.close(slave)
    try:
        # the teleop has the EE (its status line names it) and its terminal is in cbreak mode
        assert wait_for(lambda: "| EE " in log.read_text() and not termios.tcgetattr(master)[3] & termios.ICANON,
                        120), log.read_text()[-3000:]
        assert "next square_nut handle" in log.read_text()
        os.write(master, b"r")
        assert wait_for(lambda: "key r (+z)" in log.read_text(), 20), log.read_text()[-3000:]
        os.write(master, b"q")
        proc.wait(60)
    finally:
        if proc.poll() is None:
            proc.send_signal(2)
            proc.wait(30)
        os.close(master)
    text = log.read_text()
    assert proc.returncode == 0, text[-3000:]
    assert "task success: NO" in text, text[-3000:]  # the nut is still on the table
    failed = list((out / "Square" / "failed").iterdir())
    assert len(failed) == 1 and failed[0].name.startswith("teleop_") and (failed[0] / "scene.yaml").is_file()
    assert not [p for p in (out / "Square").iterdir() if p.name.startswith("teleop_")], "failed demo left behind"
