"""Several hosts, opt-in: a simulator in one network namespace and its consumers in another,
joined by a veth pair that this test creates and removes (traffic never leaves the two
namespaces). Skipped, with the reason, where namespaces cannot be created."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from mechsim.environment import RosEnvironmentError, hosts_profile

MECHSIM = [sys.executable, "-m", "mechsim.cli"]


def test_hosts_profile_opens_only_the_named_interface() -> None:
    text = hosts_profile("10.231.0.1", ["10.231.0.2"])
    white = text.split("<interfaceWhiteList>")[1].split("</interfaceWhiteList>")[0]
    assert "127.0.0.1" in white and "10.231.0.1" in white and "10.231.0.2" not in white
    assert "<useBuiltinTransports>false</useBuiltinTransports>" in text
    peers = text.split("<initialPeersList>")[1].split("</initialPeersList>")[0]
    assert "10.231.0.2" in peers


@pytest.mark.parametrize("interface,peers,field", [
    ("0.0.0.0", ["10.0.0.2"], "MECHSIM_DDS_INTERFACE"),
    ("eth0; rm -rf /", ["10.0.0.2"], "MECHSIM_DDS_INTERFACE"),
    ("10.0.0.1", ["239.255.0.1"], "MECHSIM_DDS_PEERS"),
    ("10.0.0.1", [""], "MECHSIM_DDS_PEERS"),
])
def test_bad_addresses_are_one_line(interface: str, peers: list[str], field: str) -> None:
    with pytest.raises(RosEnvironmentError, match=field):
        hosts_profile(interface, peers)


def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=60)


@pytest.fixture
def two_hosts() -> Iterator[tuple[str, str, str, str]]:
    """Namespaces (a, b) with addresses (addr_a, addr_b) on a veth pair; removed afterwards."""
    if shutil.which("ip") is None:
        pytest.skip("no `ip` command (iproute2) on this machine")
    tag = f"ms{os.getpid() % 100000}"
    a, b = f"{tag}a", f"{tag}b"
    subnet = 10 + os.getpid() % 200
    addr_a, addr_b = f"10.231.{subnet}.1", f"10.231.{subnet}.2"
    made = _ip("netns", "add", a)
    if made.returncode != 0:
        pytest.skip(f"network namespaces cannot be created here: {made.stderr.strip()}")
    etc: list[Path] = []  # only what this test made is removed
    try:
        # Two hosts have two machine ids (Fast DDS derives its host id from it and treats
        # participants with the same one as local). `ip netns exec` shows /etc/netns/NS/*
        # over /etc/*: each namespace gets its own id, removed with the namespace.
        for ns in (a, b):
            folder = Path("/etc/netns") / ns
            folder.mkdir(parents=True)
            etc.append(folder)
            (folder / "machine-id").write_text(uuid.uuid4().hex + "\n")
        steps = [("netns", "add", b),
                 ("link", "add", f"{tag}va", "type", "veth", "peer", "name", f"{tag}vb"),
                 ("link", "set", f"{tag}va", "netns", a),
                 ("link", "set", f"{tag}vb", "netns", b),
                 ("-n", a, "addr", "add", f"{addr_a}/24", "dev", f"{tag}va"),
                 ("-n", b, "addr", "add", f"{addr_b}/24", "dev", f"{tag}vb"),
                 ("-n", a, "link", "set", f"{tag}va", "up"), ("-n", a, "link", "set", "lo", "up"),
                 ("-n", b, "link", "set", f"{tag}vb", "up"), ("-n", b, "link", "set", "lo", "up")]
        for step in steps:
            r = _ip(*step)
            if r.returncode != 0:
                pytest.skip(f"veth set-up failed ({' '.join(step)}): {r.stderr.strip()}")
        yield a, b, addr_a, addr_b
    finally:
        _ip("netns", "del", a)
        _ip("netns", "del", b)
        for folder in etc:
            shutil.rmtree(folder, ignore_errors=True)


def _in(ns: str, interface: str, peer: str, env: dict[str, str]) -> tuple[list[str], dict]:
    child = dict(env, MECHSIM_DDS_INTERFACE=interface, MECHSIM_DDS_PEERS=peer)
    return ["ip", "netns", "exec", ns], child


def test_simulator_and_consumer_on_two_hosts(two_hosts: tuple[str, str, str, str],
                                            ros_env: dict[str, str], tmp_path: Path) -> None:
    a, b, addr_a, addr_b = two_hosts
    scene = tmp_path / "scene.yaml"
    scene.write_text("name: hosts\nsystems:\n  - {system: pendulum}\n")
    pre_a, env_a = _in(a, addr_a, addr_b, ros_env)
    pre_b, env_b = _in(b, addr_b, addr_a, ros_env)
    sim = subprocess.Popen([*pre_a, *MECHSIM, "run", str(scene), "--only", "pendulum"],
                           env=env_a, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True)
    try:
        echo = subprocess.run([*pre_b, *MECHSIM, "topic", "echo", "/pendulum/energy",
                               "--count", "20", "--timeout", "120"], env=env_b,
                              capture_output=True, text=True, timeout=300)
        assert echo.returncode == 0, echo.stderr
        assert echo.stdout.count("total:") == 20
        # The diagnostics node on the other host checks the simulator's laws over the link.
        diag = subprocess.Popen([*pre_b, *MECHSIM, "run", str(scene), "--only", "diagnostics"],
                                env=env_b, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
        try:
            ok = subprocess.run([*pre_b, *MECHSIM, "topic", "echo", "/diagnostics", "--count",
                                 "3", "--timeout", "120"], env=env_b, capture_output=True,
                                text=True, timeout=300)
        finally:
            diag.terminate()
            diag.wait(timeout=60)
        assert ok.returncode == 0, ok.stderr
        assert "name: mechsim/pendulum/energy" in ok.stdout
        # The loopback default does not cross: a consumer without the profile sees nothing.
        alone = subprocess.run([*pre_b, *MECHSIM, "topic", "echo", "/pendulum/energy",
                                "--once", "--timeout", "5"], env=ros_env, capture_output=True,
                               text=True, timeout=300)
        assert alone.returncode == 2 and "/pendulum/energy" in alone.stderr
    finally:
        sim.terminate()
        sim.wait(timeout=60)


def test_recorder_on_the_other_host_records_every_message(
        two_hosts: tuple[str, str, str, str], ros_env: dict[str, str], tmp_path: Path) -> None:
    """The simulator on host a waits for the recorder on host b (``--wait-for recorder``), runs
    2 s as fast as it can, and every message it published is in b's bag."""
    from rosbags.highlevel import AnyReader

    a, b, addr_a, addr_b = two_hosts
    pre_a, env_a = _in(a, addr_a, addr_b, ros_env)
    pre_b, env_b = _in(b, addr_b, addr_a, ros_env)
    bag = tmp_path / "bag"
    rec = subprocess.Popen([*pre_b, *MECHSIM, "run", "pendulum", "--only", "recorder", "--bag",
                            str(bag)], env=env_b, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    try:
        sim = subprocess.run([*pre_a, *MECHSIM, "run", "pendulum", "--only", "pendulum",
                              "--wait-for", "recorder", "--fast", "--duration", "2"],
                             env=env_a, capture_output=True, text=True, timeout=300)
        assert sim.returncode == 0, sim.stderr
        assert "stepping anyway" not in sim.stderr
    finally:
        rec.send_signal(signal.SIGINT)
        out, err = rec.communicate(timeout=120)
    assert rec.returncode == 0 and "Traceback" not in err, err
    counts: dict[str, int] = {}
    with AnyReader([bag]) as reader:
        for con, _, _ in reader.messages():
            counts[con.topic] = counts.get(con.topic, 0) + 1
    samples = ("/pendulum/state", "/pendulum/energy", "/pendulum/observables", "/tf", "/clock")
    assert {t: counts.get(t) for t in samples} == dict.fromkeys(samples, 201)
    assert counts["/pendulum/system_info"] == 1 and counts["/tf_static"] == 1
