"""The temporary Prefect API a command starts early (pipelines/prefect_api.py), in processes of
its own: it answers, it stops with the command (also a killed one), and a configured API wins."""

import os
import signal
import subprocess
import sys
import textwrap
import time
import urllib.request

import pytest

from tests.test_task_runner_address import _processes_in

_START = textwrap.dedent("""
    import sys, time, urllib.request
    from pipelines import prefect_api
    prefect_api.start_early()
    imported = "prefect" in sys.modules  # started before Prefect is imported (1-2 s)
    url = prefect_api.api_url()
    with urllib.request.urlopen(url + "/health", timeout=10) as r:
        print(url, r.status, imported, flush=True)
    if sys.argv[1] == "wait":
        time.sleep(600)
""")


def _env(tmp_path, **extra) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PREFECT_API")}
    env.update(PYTHONPATH=os.pathsep.join(sys.path), TMPDIR=str(tmp_path), PREFECT_HOME=str(tmp_path / "home"), **extra)
    return env


def _gone_within(tmp_path, seconds: float) -> list[int]:
    deadline = time.monotonic() + seconds
    while (left := _processes_in(tmp_path)) and time.monotonic() < deadline:
        time.sleep(0.5)
    return left


@pytest.mark.slow
def test_the_temporary_api_answers_and_stops_with_the_command(tmp_path):
    out = subprocess.run([sys.executable, "-c", _START, "exit"], cwd=tmp_path, env=_env(tmp_path),
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    url, status, imported = out.stdout.split()
    assert url.startswith("http://127.0.0.1:") and url.endswith("/api") and status == "200" and imported == "False"
    assert not _gone_within(tmp_path, 10), "the server outlived its command"
    assert not list(tmp_path.glob("stormlane-prefect-api-*")), "its log was left behind"
    with pytest.raises(OSError):
        urllib.request.urlopen(url + "/health", timeout=2)


@pytest.mark.slow
def test_a_killed_command_does_not_leave_its_server_running(tmp_path):
    run = subprocess.Popen([sys.executable, "-c", _START, "wait"], cwd=tmp_path, env=_env(tmp_path),
                           stdout=subprocess.PIPE, text=True)
    try:
        url = run.stdout.readline().split()[0]
        assert len(_processes_in(tmp_path)) == 2  # the command and its server
        run.send_signal(signal.SIGKILL)  # no atexit: the server notices its parent is gone
        run.wait(timeout=30)
        assert not _gone_within(tmp_path, 15), "the server outlived its killed command"
        assert not list(tmp_path.glob("stormlane-prefect-api-*")), "its log was left behind"
    finally:
        run.kill()
    with pytest.raises(OSError):
        urllib.request.urlopen(url + "/health", timeout=2)


def test_an_api_set_in_a_profile_wins_and_the_early_server_stops(tmp_path):
    # PREFECT_API_URL only in the active profile: start_early cannot see it without importing
    # Prefect, so it starts a server; api_url then finds the profile's URL and stops that server
    home = tmp_path / "home"
    home.mkdir()
    (home / "profiles.toml").write_text('active = "team"\n\n[profiles.team]\nPREFECT_API_URL = "http://10.9.8.7:4200/api"\n')
    code = ("import time\nfrom pipelines import prefect_api\nprefect_api.start_early()\n"
            "started = prefect_api._server is not None\nprint(prefect_api.api_url(), started, flush=True)\n"
            "time.sleep(600)")
    run = subprocess.Popen([sys.executable, "-c", code], cwd=tmp_path, env=_env(tmp_path), stdout=subprocess.PIPE,
                           text=True)
    try:
        assert run.stdout.readline().split() == ["http://10.9.8.7:4200/api", "True"]
        assert _processes_in(tmp_path) == [run.pid], "the early server still runs beside the configured API"
        assert not list(tmp_path.glob("stormlane-prefect-api-*"))
    finally:
        run.kill()
        run.wait(timeout=30)



def test_a_server_that_cannot_start_is_one_line_naming_why(tmp_path):
    code = ("from pipelines import prefect_api\nprefect_api.start_early()\n"
            "try:\n    prefect_api.api_url()\nexcept prefect_api.PrefectApiError as err:\n    print(err)\n")
    env = _env(tmp_path, PREFECT_API_DATABASE_CONNECTION_URL=f"sqlite+aiosqlite:///{tmp_path}/no/such/dir/p.db")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    line = out.stdout.strip()
    assert len(line.splitlines()) == 1 and line.startswith("the temporary Prefect API server exited (code "), line
    assert "unable to open database file" in line and "PREFECT_API_URL" in line
    assert not list(tmp_path.glob("stormlane-prefect-api-*"))
