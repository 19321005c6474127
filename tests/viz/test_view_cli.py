"""``viz3d view`` flags: one validation with scene keys, clear errors with exit code 2, the
scene's own speed, addresses that cannot be served (issue 8)."""

import socket
import threading
import time

import pytest

from viz3d.cli import main

from conftest import SCENES

SCENE = str(SCENES / "heavy_top.toml")
#: TEST-NET-1 (RFC 5737): never an address of this machine.
FOREIGN_HOST = "192.0.2.1"


def _exit_code(argv) -> int:
    """``main``'s exit code, also where argparse ends it with ``SystemExit``."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def _viz3d_threads():
    return [t.name for t in threading.enumerate() if t.name.startswith("viz3d")]


@pytest.mark.parametrize("flag, value, expected", [
    ("--speed", "0", "a positive number"), ("--speed", "-1", "a positive number"),
    ("--speed", "nan", "a positive number"), ("--speed", "fast", "a positive number"),
    ("--port", "99999", "an integer 0..65535"), ("--port", "-1", "an integer 0..65535"),
    ("--port", "80.5", "an integer 0..65535"),
    ("--duration", "0", "a positive number"), ("--duration", "inf", "a positive number"),
])
def test_bad_viewer_flags_exit_2_naming_the_flag(flag, value, expected, capsys):
    for cmd in (["view", SCENE], ["run", SCENE, "--view"]):
        assert _exit_code([*cmd, flag, value]) == 2
        err = capsys.readouterr().err
        assert f"argument {flag}: expected {expected}, got '{value}'" in err, err
        assert "Traceback" not in err


def test_host_that_is_not_on_this_machine_fails_at_once_and_leaves_nothing(tmp_path, capsys):
    record = tmp_path / "never.rrd"
    t0 = time.monotonic()
    code = main(["view", SCENE, "--host", FOREIGN_HOST, "--port", "0", "--record", str(record), "--duration", "2"])
    assert code == 2
    err = capsys.readouterr().err
    assert f"argument --host: cannot serve on host {FOREIGN_HOST!r}" in err and "assign requested address" in err.lower(), err
    assert time.monotonic() - t0 < 30          # a generous bound: the bug was a hang
    assert not record.exists() and not _viz3d_threads()


def test_busy_port_serves_on_the_next_one_and_prints_the_real_url(capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["view", SCENE, "--port", str(port), "--duration", "0.5"]) == 0
    out = capsys.readouterr().out
    line = next(s for s in out.splitlines() if s.startswith("viz3d viewer: open"))
    assert f"http://127.0.0.1:{port}" not in line and "http://127.0.0.1:" in line
    assert f"port {port} is busy" in line


def test_view_uses_the_scene_speed_unless_given_and_says_it_waits_for_a_browser(capsys):
    bronze = str(SCENES / "impact_bronze_ball.toml")
    assert main(["view", bronze, "--port", "0", "--duration", "0.3"]) == 0
    line = next(s for s in capsys.readouterr().out.splitlines() if s.startswith("viz3d viewer: open"))
    assert "speed 5e-05x" in line and "starts when a browser connects" in line, line
    assert main(["view", bronze, "--port", "0", "--duration", "0.3", "--speed", "1e-4"]) == 0
    line = next(s for s in capsys.readouterr().out.splitlines() if s.startswith("viz3d viewer: open"))
    assert "speed 0.0001x" in line, line
    assert not _viz3d_threads()
