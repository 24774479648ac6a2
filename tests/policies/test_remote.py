"""Evaluation through LeRobot's own remote inference (`policies.remote`): LeRobot's PolicyServer (its class, set up
as its `serve()` does, on a free loopback port in this process) serving a small ACT checkpoint to `aerobench eval`;
the trust rule for non-loopback servers; a server that is down or answers garbage is one line."""

import contextlib
import json
import logging
import pickle
import socket
import types
from concurrent import futures
from pathlib import Path

import pytest
import torch

from aerobench.envs.platforms import PLATFORMS
from aerobench.eval.evaluate import EvalConfig, evaluate
from aerobench.policies import remote
from aerobench.policies.remote import PolicyServerError, PolicyServerSpec, RemotePolicy, ServerSession
from tests.cli_here import aerobench_here

from .tiny_act import write_tiny_act

REPO = Path(__file__).resolve().parents[2]
COMMITTED_ACT = REPO / "leaderboards" / "checkpoints" / "TidyHouse" / "act_state" / "place"
PICKS = ["--setting", "TidyHouse", "--skills", "pick", "--objects", "master_chef_can", "--episodes-per-object", "2",
         "--max-steps", "5"]


@pytest.fixture(scope="module")
def tiny_act(tmp_path_factory) -> Path:
    return write_tiny_act(tmp_path_factory.mktemp("act") / "pretrained_model")


@pytest.fixture(autouse=True)
def fresh_sessions():
    """Each test talks to its own servers: no channel or loaded policy carried over from another test."""
    yield
    remote._SESSIONS.clear()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _grpc_server(servicer, port: int | None = None) -> tuple:
    import grpc
    from lerobot.transport import services_pb2_grpc  # type: ignore

    port = port or free_port()
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=4))
    services_pb2_grpc.add_AsyncInferenceServicer_to_server(servicer, server)
    server.add_insecure_port(f"127.0.0.1:{port}")
    server.start()
    return server, f"127.0.0.1:{port}"


@contextlib.contextmanager
def lerobot_policy_server(folder: Path):
    """LeRobot's PolicyServer as `python -m lerobot.async_inference.policy_server --host=127.0.0.1 --port=P --fps=20
    --inference_latency=0` sets it up; yields (address, grpc server)."""
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    with contextlib.chdir(folder):  # importing it opens a log file under ./logs and takes over the root logger
        from lerobot.async_inference.configs import PolicyServerConfig
        from lerobot.async_inference.policy_server import PolicyServer
    root.handlers[:] = handlers
    root.setLevel(level)
    port = free_port()
    config = PolicyServerConfig(host="127.0.0.1", port=port, fps=20, inference_latency=0.0)
    server, address = _grpc_server(PolicyServer(config), port)
    try:
        yield address, server
    finally:
        server.stop(0)


def fake_env(seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    env = types.SimpleNamespace(num_envs=1, platform=PLATFORMS["gripper"], device="cpu",
                                get_instruction=lambda i: "pick up the master chef can from the dresser")
    obs = {"agent": {"state": torch.randn(1, 19, generator=g)},
           "sensor_data": {"drone_front": {"rgb": torch.randint(0, 256, (1, 128, 128, 3), generator=g, dtype=torch.uint8)}}}
    return env, obs


def error_line(proc) -> str:
    lines = [line for line in proc.stderr.splitlines() if line.startswith("aerobench eval: error:")]
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr[-2000:]
    return lines[0]


# ----------------------------------------------------------------------------------------------------------------------
def test_only_loopback_unless_the_server_is_trusted():
    for address in ("127.0.0.1:8080", "localhost:1", "[::1]:9000", "127.0.0.5:80"):
        PolicyServerSpec((address,))
    for address in ("10.0.0.5:8080", "gpu-box:8080", "[2001:db8::1]:8080"):
        with pytest.raises(ValueError, match="is not a loopback address.*pass --trust-policy-server"):
            PolicyServerSpec((address,))
        PolicyServerSpec((address,), trust=True)
    for bad in ("8080", "host:", "host:http", "host:70000"):
        with pytest.raises(ValueError, match="--policy-server takes HOST:PORT"):
            PolicyServerSpec((bad,))


def test_a_remote_server_without_the_flag_is_one_line(tmp_path):
    line = error_line(aerobench_here("eval", "--policy-server", "192.168.1.20:8080", "--policy-type", "act",
                                     "--checkpoint", str(COMMITTED_ACT), *PICKS, "--out", str(tmp_path / "x")))
    assert "not a loopback address" in line and "unpickling runs any code" in line and "--trust-policy-server" in line
    assert not (tmp_path / "x").exists()


ACT_PICK = ["--checkpoint", str(COMMITTED_ACT.parent / "pick")]


@pytest.mark.parametrize("args, says", [
    (["--policy-type", "act", *ACT_PICK], "--policy-type, --policy-device and --trust-policy-server go with "
                                          "--policy-server"),
    (ACT_PICK, "give --policy (or --policy-server with --policy-type)"),
    (["--policy-server", "127.0.0.1:9", *ACT_PICK], "--policy-server needs --policy-type"),
    (["--policy-server", "127.0.0.1:9", "--policy", "expert"], "--policy-type takes a LeRobot policy aerobench "
                                                                "evaluates (act, diffusion, pi0, pi05), got 'expert'"),
    (["--policy-server", "127.0.0.1:9", "--policy-type", "act", "--policy", "pi05", *ACT_PICK], "disagree"),
    (["--policy-server", "127.0.0.1:9", "--policy-type", "act", "--workers", "2", *ACT_PICK],
     "give one server per worker"),
    (["--policy", "expert", "--realtime", "--chain", "pick,transport,place"],
     "--realtime and --policy-server evaluate single skills"),
])
def test_eval_options_are_checked_in_one_line(args, says, tmp_path):
    line = error_line(aerobench_here("eval", *args, "--setting", "TidyHouse", "--out", str(tmp_path / "x")))
    assert says in line
    assert not (tmp_path / "x").exists()


def test_a_checkpoint_the_server_cannot_feed_is_refused_with_the_reason(tmp_path):
    """The committed ACT checkpoints read the privileged task state, which LeRobot's server drops."""
    line = error_line(aerobench_here("eval", "--policy-server", f"127.0.0.1:{free_port()}", "--policy-type", "act",
                                     "--checkpoint", str(COMMITTED_ACT), *PICKS, "--out", str(tmp_path / "x")))
    assert "reads observation.environment_state, which LeRobot's PolicyServer does not build" in line


def test_a_server_that_is_down_is_one_line(tiny_act, tmp_path):
    address = f"127.0.0.1:{free_port()}"
    line = error_line(aerobench_here("eval", "--policy-server", address, "--policy-type", "act", "--checkpoint",
                                     str(tiny_act), *PICKS, "--out", str(tmp_path / "x")))
    assert f"no policy server answers at {address} (UNAVAILABLE while connecting)" in line
    assert "lerobot.async_inference.policy_server" in line


class GarbageServer:
    """Speaks LeRobot's AsyncInference service but answers GetActions with `reply` (bytes of the Actions message)."""

    def __init__(self, reply: bytes):
        from lerobot.transport import services_pb2  # type: ignore

        self.pb, self.reply = services_pb2, reply

    def Ready(self, request, context):  # noqa: N802 (gRPC method names)
        return self.pb.Empty()

    def SendPolicyInstructions(self, request, context):  # noqa: N802
        return self.pb.Empty()

    def SendObservations(self, request_iterator, context):  # noqa: N802
        for _ in request_iterator:
            pass
        return self.pb.Empty()

    def GetActions(self, request, context):  # noqa: N802
        return self.pb.Actions(data=self.reply) if self.reply else self.pb.Empty()


def _timed(timestep: int, action) -> list:
    from lerobot.async_inference.helpers import TimedAction

    return [TimedAction(timestamp=0.0, timestep=timestep, action=action)]


@pytest.mark.parametrize("reply, says", [  # (what the server's GetActions answers, made when the test runs)
    (lambda: b"", "answered no actions for observation #1 (its policy failed on it"),
    (lambda: b"\x80\x05not a pickle", "not an action chunk (UnpicklingError)"),
    (lambda: pickle.dumps({"action": 1}), "not an action chunk (a dict; expected 1 to 3 TimedActions)"),
    (lambda: pickle.dumps(_timed(7, torch.zeros(5))), "it answers observation #7: is another client using that server?"),
    (lambda: pickle.dumps(_timed(1, torch.zeros(3))), "actions of 3 values, expected 5 finite ones"),
    (lambda: pickle.dumps(_timed(1, torch.full((5,), float("nan")))), "expected 5 finite ones"),
], ids=["empty", "not-a-pickle", "a-dict", "another-observation", "wrong-size", "nan"])
def test_garbage_answers_are_one_line(reply, says):
    server, address = _grpc_server(GarbageServer(reply()))
    try:
        with pytest.raises(PolicyServerError) as error:
            ServerSession(address).chunk({"state_0": 0.0, "task": "x"}, action_dim=5, max_len=3)
    finally:
        server.stop(0)
    assert says in str(error.value) and "\n" not in str(error.value) and address in str(error.value)


def test_the_server_builds_the_inputs_a_local_policy_gets(tiny_act):
    """The raw robot observation the client sends, turned into policy inputs by LeRobot's server code, is the batch a
    local policy reads: the same state and the same RGB floats."""
    from lerobot.async_inference.helpers import raw_observation_to_observation

    from aerobench.policies.lerobot_policies import lerobot_batch

    env, obs = fake_env()
    _, config = remote.served_config("act", str(tiny_act))
    inputs = remote.ServedInputs(env, dict(config.input_features))
    (raw,) = inputs.raw_observations(obs)
    served = raw_observation_to_observation(raw, inputs.features(), config.image_features)
    local = lerobot_batch(env, obs, inputs.inputs)
    assert set(served) == {"observation.state", "observation.images.drone_front", "task"}
    assert torch.equal(served["observation.state"], local["observation.state"])
    assert torch.equal(served["observation.images.drone_front"], local["observation.images.drone_front"])
    assert served["task"] == local["task"][0]


def test_served_chunks_are_the_local_policys_chunks(tiny_act, tmp_path):
    from aerobench.policies.lerobot_policies import LeRobotPolicy

    env, obs = fake_env()
    local = LeRobotPolicy(env, checkpoint=str(tiny_act))
    chunk = local.act_chunk(obs)
    assert chunk.shape == (1, 3, 5)
    local.reset(torch.arange(1))
    played = torch.stack([local.act(obs) for _ in range(3)], dim=1)  # select_action's queue, action by action
    assert torch.equal(chunk, played)
    with lerobot_policy_server(tmp_path) as (address, _):
        served = RemotePolicy(env, address, "act", str(tiny_act))
        remote_chunk = served.act_chunk(obs)
        played = torch.stack([served.act(obs) for _ in range(3)], dim=1)
    # not bit for bit: the server's own copy of the model answered 2.4e-7 apart when this was written
    torch.testing.assert_close(remote_chunk, chunk, rtol=0, atol=1e-5)
    torch.testing.assert_close(played, chunk, rtol=0, atol=1e-5)


def test_eval_through_the_server_keeps_finished_episodes_and_resumes(tiny_act, tmp_path):
    """Two short Pick episodes with cameras; the server goes away after the first: one line, the first episode kept;
    the same command against a server started elsewhere finishes the second."""
    out = tmp_path / "eval"
    with lerobot_policy_server(tmp_path) as (address, server):
        config = EvalConfig(policy="act", setting="TidyHouse", skills=("pick",), objects=("master_chef_can",),
                            episodes_per_object=2, checkpoint=str(tiny_act), max_steps=5,
                            policy_server=PolicyServerSpec((address,)))
        with pytest.raises(PolicyServerError, match=f"no policy server answers at {address} .*finished so far are kept"):
            evaluate(config, out, on_episode=lambda episode, progress: server.stop(0))
    records = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    assert [r["episode_index"] for r in records] == [0] and not (out / "results.json").exists()

    with lerobot_policy_server(tmp_path) as (address, _):
        proc = aerobench_here("eval", "--policy-server", address, "--policy-type", "act", "--checkpoint",
                              str(tiny_act), *PICKS, "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-2000:]
    results = json.loads((out / "results.json").read_text())
    assert results["policy"] == "act" and results["provenance"]["policy_server"] == [address]
    records = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    assert [r["episode_index"] for r in records] == [0, 1] and all(r["steps"] == 5 for r in records)
    assert results["cells"][0]["n"] == 2


def test_realtime_eval_through_the_server(tiny_act, tmp_path):
    """`--realtime` with the policy's own latency: each request's round trip through LeRobot's server."""
    out = tmp_path / "eval"
    with lerobot_policy_server(tmp_path) as (address, _):
        proc = aerobench_here("eval", "--policy-server", address, "--policy-type", "act", "--checkpoint",
                              str(tiny_act), "--setting", "TidyHouse", "--skills", "pick", "--objects",
                              "master_chef_can", "--episodes-per-object", "1", "--max-steps", "6", "--realtime",
                              "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads((out / "results.json").read_text())["provenance"]["realtime"]["latency_ms"] == "measured"
    (record,) = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    timing = record["extra"]["realtime"]
    assert timing["requests"] >= 2 and timing["latency_ms_mean"] > 0 and timing["latency_steps_max"] >= 1
    assert timing["held_steps"] >= 1  # the first answer comes at least one step after its observation
    assert timing["command_age_steps_max"] >= timing["latency_steps_max"]
