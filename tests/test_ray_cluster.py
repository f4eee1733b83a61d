"""``--executor ray`` on a Ray cluster as ``ray start`` makes them today: two nodes on 127.0.0.1 (a head and a
second raylet) with token authentication (Ray 2.60 and later). A driver without the token is refused by the
cluster: one line naming Ray's words and what to set, at once (it waited 20 s and blamed the workers); with
``RAY_AUTH_MODE=token`` and the token, the episodes run on the cluster and their records are a local run's.

The cluster's processes run in sessions of their own under a short temporary folder (Ray's unix sockets live
there), with a HOME of their own (no token of the machine's is read or written); every one is stopped by the test.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from conftest import REPO
from test_ray_executor import _episodes_file, _eval_args, _serial_reference, _sorted_records
from test_robot_bridge import free_port

ray = pytest.importorskip("ray")
START_S = 120.0
"""The longest a node may take to start (a generous bound on a loaded machine; it takes seconds)."""


@dataclass(frozen=True)
class TokenCluster:
    address: str
    token: str
    home: Path

    def env(self, with_token: bool) -> dict[str, str]:
        """drivenav's environment: the machine's, no Ray token settings, the cluster's HOME; ``with_token``: the
        token mode and the cluster's token."""
        env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH")}
        env.update(HOME=str(self.home), RAY_USAGE_STATS_ENABLED="0")
        if with_token:
            env.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=self.token)
        return env


def _start_node(command: list[str], env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    """``ray start ... --block`` in a session of its own, waited for until it says the runtime started."""
    with log.open("wb") as out:
        node = subprocess.Popen(command, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    deadline = time.monotonic() + START_S
    while "Ray runtime started" not in log.read_text(errors="replace"):
        if node.poll() is not None or time.monotonic() > deadline:
            _stop_node(node)
            pytest.fail(f"ray start did not start: {log.read_text(errors='replace')[-2000:]}")
        time.sleep(0.2)
    return node


def _stop_node(node: subprocess.Popen[bytes]) -> None:
    """SIGTERM (``ray start --block`` stops its node's processes), then SIGKILL to whatever of its session is
    left."""
    if node.poll() is None:
        node.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            node.wait(60)
    with contextlib.suppress(ProcessLookupError):
        os.killpg(node.pid, signal.SIGKILL)
    node.wait()


@pytest.fixture(scope="module")
def token_cluster() -> Iterator[TokenCluster]:
    if not hasattr(ray.exceptions, "AuthenticationError"):
        pytest.skip(f"Ray {ray.__version__} has no token authentication")
    ray_cli = Path(sys.executable).with_name("ray")
    if not ray_cli.exists():
        pytest.skip("no ray command beside this interpreter")
    home = Path(tempfile.mkdtemp(prefix="dn-ray-"))
    cluster = TokenCluster(f"127.0.0.1:{free_port()}", secrets.token_hex(16), home)
    env = {**cluster.env(with_token=True), "RAY_USAGE_STATS_ENABLED": "0"}
    node_options = ["--block", "--node-ip-address", "127.0.0.1", "--num-cpus", "1", "--disable-usage-stats"]
    node_options += ["--min-worker-port", "0", "--max-worker-port", "0"]
    head_options = ["--head", "--port", cluster.address.rsplit(":", 1)[1], "--include-dashboard", "false"]
    head_options += ["--temp-dir", str(home / "ray"), "--dashboard-port", str(free_port())]
    nodes: list[subprocess.Popen[bytes]] = []
    try:
        nodes.append(_start_node([str(ray_cli), "start", *head_options, *node_options], env, home / "head.log"))
        worker = [str(ray_cli), "start", "--address", cluster.address, *node_options]
        nodes.append(_start_node(worker, env, home / "node.log"))
        _wait_for_two_nodes(cluster)
        yield cluster
    finally:
        for node in reversed(nodes):
            _stop_node(node)
        shutil.rmtree(home, ignore_errors=True)


def _wait_for_two_nodes(cluster: TokenCluster) -> None:
    """Both raylets registered with the head (asked with the token)."""
    count = (
        "import ray, sys, time\n"
        f"ray.init(address={cluster.address!r}, include_dashboard=False, log_to_driver=False)\n"
        f"deadline = time.monotonic() + {START_S}\n"
        "while sum(n['Alive'] for n in ray.nodes()) < 2 and time.monotonic() < deadline:\n"
        "    time.sleep(0.2)\n"
        "print(sum(n['Alive'] for n in ray.nodes()))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", count],
        env=cluster.env(with_token=True),
        capture_output=True,
        text=True,
        timeout=2 * START_S,
        check=False,
    )
    assert result.stdout.strip().splitlines()[-1:] == ["2"], result.stderr[-2000:]


def _eval(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "drivenav.cli", *args]
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=600, cwd=REPO, check=False)


def test_a_token_cluster_refuses_a_driver_without_the_token_in_one_line_naming_what_to_set(
    tmp_path: Path, token_cluster: TokenCluster
) -> None:
    """It stopped after 20 s with "no Ray worker ran a task ... Ray's workers die as they start"."""
    args = _eval_args(_episodes_file(tmp_path), tmp_path / "refused")
    result = _eval([*args, "--executor", "ray", "--ray-address", token_cluster.address], token_cluster.env(False))
    assert result.returncode == 2, result.stderr
    message = result.stderr.strip().splitlines()[-1]  # after the progress bar's lines
    assert message.startswith("drivenav: error: command line: field '--ray-address'"), message
    assert "RAY_AUTH_MODE=token" in message and "RAY_AUTH_TOKEN" in message and token_cluster.address in message
    assert "Authentication token is missing or incorrect" in message
    assert "Traceback" not in result.stderr and "workers die" not in message
    assert not (tmp_path / "refused" / "episodes.jsonl").exists()


def test_a_token_cluster_runs_the_episodes_given_the_token_as_a_local_run_does(
    tmp_path: Path, token_cluster: TokenCluster
) -> None:
    reference = _serial_reference(tmp_path)
    out = tmp_path / "cluster"
    args = _eval_args(tmp_path / "episodes.json.gz", out)
    ray_args = ["--executor", "ray", "--ray-address", token_cluster.address, "--workers", "2"]
    result = _eval([*args, *ray_args], token_cluster.env(with_token=True))
    assert result.returncode == 0, result.stderr[-3000:]
    assert _sorted_records(out) == reference


def test_token_mode_without_a_token_names_what_to_set(tmp_path: Path) -> None:
    """``RAY_AUTH_MODE=token`` and no token anywhere: Ray's AuthenticationError, which the worker probe printed as
    its traceback's last line under "a Ray worker could not run a task" (exit 1)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH")}
    env.update(HOME=str(tmp_path), RAY_AUTH_MODE="token", RAY_USAGE_STATS_ENABLED="0")
    args = _eval_args(_episodes_file(tmp_path), tmp_path / "refused")
    result = _eval([*args, "--executor", "ray", "--ray-address", f"127.0.0.1:{free_port()}"], env)
    assert result.returncode == 2, result.stderr
    message = result.stderr.strip().splitlines()[-1]
    assert message.startswith("drivenav: error: command line: field '--ray-address': expected a token"), message
    assert "RAY_AUTH_TOKEN" in message and "Traceback" not in result.stderr
