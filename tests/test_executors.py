"""Benchmark executors: job order, errors naming the job, cancellation, Ray on a real local instance."""

import os
import socket
import sys
import time

import pytest

from deploy.bench.executors import LocalExecutor, RayExecutor, make_executor
from deploy.bench.open import simulate_episode
from deploy.control.state import StopReason
from deploy.errors import USER_ERRORS, ConfigError, JobError, ModelError


def square(x: int, delay_s: float = 0.0, marker: str | None = None) -> dict:
    """A picklable job: x*x after `delay_s`, in the process that ran it; x < 0 is an error."""
    time.sleep(delay_s)
    if x < 0:
        raise ValueError(f"x must be >= 0, got {x}")
    if marker is not None:
        open(marker, "w").close()
    return {"x": x, "y": x * x, "pid": os.getpid()}


def needs_weights(x: int) -> dict:
    """A picklable job failing as a job without model weights does (a user's one-line error)."""
    if x == 2:
        raise ModelError("model facebook/sam2.1-hiera-tiny is not in the Hugging Face cache; fetch it with "
                         "`hf download facebook/sam2.1-hiera-tiny`")
    if x == 3:
        raise ConfigError("invalid configuration: give a value in range")
    return {"x": x}


DESCENDING_DELAYS = [dict(x=x, delay_s=0.1 * (3 - x)) for x in range(4)]  # the first job finishes last


def closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture(scope="module")
def ray_executor():
    import ray.cloudpickle  # the cluster extra: scripts/setup.sh installs it

    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # tests/ is not importable on Ray workers
    with RayExecutor("local", num_cpus=2) as executor:
        yield executor


def test_in_process_runs_jobs_here_in_order():
    results = list(LocalExecutor(1).map(square, [dict(x=x) for x in range(5)]))
    assert [r["y"] for r in results] == [0, 1, 4, 9, 16]
    assert {r["pid"] for r in results} == {os.getpid()}


def test_process_pool_yields_in_job_order_though_later_jobs_finish_first():
    results = list(LocalExecutor(2).map(square, DESCENDING_DELAYS))
    assert [r["x"] for r in results] == [0, 1, 2, 3]
    assert os.getpid() not in {r["pid"] for r in results}


@pytest.mark.parametrize("workers", [1, 2])
def test_local_error_names_the_job_after_yielding_the_earlier_ones(workers):
    jobs = [dict(x=1), dict(x=2), dict(x=-3), dict(x=4)]
    seen = []
    with pytest.raises(JobError, match=r"job 3 of 4 failed: test_executors\.square\(x=-3\) raised ValueError: "
                                       r"x must be >= 0, got -3") as info:
        for result in LocalExecutor(workers).map(square, jobs):
            seen.append(result["x"])
    assert seen == [1, 2]
    assert info.value.job == {"x": -3}
    assert isinstance(info.value.__cause__, ValueError)
    assert isinstance(info.value, USER_ERRORS)


@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize(("x", "error"), [(2, ModelError), (3, ConfigError)])
def test_a_jobs_model_or_config_error_passes_through_unwrapped(workers, x, error):
    """Its message already names the thing, the cause and the fix: not buried in a JobError about job N."""
    with pytest.raises(error) as info:
        list(LocalExecutor(workers).map(needs_weights, [dict(x=1), dict(x=x)]))
    assert type(info.value) is error and not str(info.value).startswith("job ")


def test_process_pool_cancels_waiting_jobs_after_a_failure(tmp_path):
    jobs = [dict(x=-1)] + [dict(x=x, delay_s=0.2, marker=str(tmp_path / f"{x}")) for x in range(1, 21)]
    with pytest.raises(JobError, match="job 1 of 21"):
        list(LocalExecutor(2).map(square, jobs))
    assert len(list(tmp_path.iterdir())) < 10  # 20 jobs of 0.2 s on 2 workers would take 2 s


def test_make_executor_chooses_by_ray_address():
    local = make_executor(3, None)
    assert isinstance(local, LocalExecutor) and local.workers == 3
    ray = make_executor(3, "ray://head.example:10001")  # nothing connects before the executor is used
    assert isinstance(ray, RayExecutor) and ray.address == "ray://head.example:10001"


@pytest.mark.parametrize("address", ["", "head.example", "ray://", "host:port", "ray://host:99999"])
def test_bad_ray_address_is_a_config_error(address):
    with pytest.raises(ConfigError, match="not a Ray address; use local, auto, ray://HOST:PORT or HOST:PORT"):
        RayExecutor(address)


def test_cpu_count_only_for_a_local_instance():
    with pytest.raises(ConfigError, match="applies only to a local instance"):
        RayExecutor("auto", num_cpus=2)
    with pytest.raises(ConfigError, match="applies only to a local instance"):
        RayExecutor("local", num_cpus=0)


def test_missing_ray_names_the_cluster_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError, as without the extra
    with pytest.raises(ConfigError, match=r"Ray is not installed; install it with pip install 'axisloop\[cluster\]'"):
        with RayExecutor("local"):
            pass


@pytest.mark.parametrize("scheme", ["ray://", ""])
def test_unreachable_cluster_fails_fast(scheme):
    address = f"{scheme}127.0.0.1:{closed_port()}"
    start = time.perf_counter()
    with pytest.raises(ConfigError, match=f"--ray {address}: Ray cluster unreachable"):
        with RayExecutor(address):
            pass
    assert time.perf_counter() - start < 10  # Ray alone retries for minutes


def test_ray_yields_in_job_order_from_worker_processes(ray_executor):
    results = list(ray_executor.map(square, DESCENDING_DELAYS))
    assert [r["y"] for r in results] == [0, 1, 4, 9]
    assert os.getpid() not in {r["pid"] for r in results}


def test_ray_error_names_the_job_with_the_original_cause(ray_executor):
    seen = []
    with pytest.raises(JobError, match=r"job 2 of 3 failed: test_executors\.square\(x=-2\) raised ValueError: "
                                       r"x must be >= 0, got -2") as info:
        for result in ray_executor.map(square, [dict(x=1), dict(x=-2), dict(x=3)]):
            seen.append(result["x"])
    assert seen == [1]
    assert isinstance(info.value.__cause__.cause, ValueError)  # RayTaskError keeps the worker's exception


def test_ray_passes_a_jobs_model_error_through(ray_executor):
    with pytest.raises(ModelError, match="hf download facebook/sam2.1-hiera-tiny"):
        list(ray_executor.map(needs_weights, [dict(x=1), dict(x=2)]))


def test_ray_starts_no_more_jobs_after_a_failure(ray_executor, tmp_path):
    jobs = [dict(x=-1)] + [dict(x=x, delay_s=0.2, marker=str(tmp_path / f"{x}")) for x in range(1, 21)]
    with pytest.raises(JobError, match="job 1 of 21"):
        list(ray_executor.map(square, jobs))
    time.sleep(3.0)  # submitted all at once, 20 jobs of 0.2 s on 2 CPUs would all be done by now
    assert len(list(tmp_path.iterdir())) < 10


def test_ray_runs_a_simulated_episode(ray_executor):
    job = dict(task="drawer", seed=0, split="train", target=0.05, world="box")
    (result,) = ray_executor.map(simulate_episode, [job])
    assert (result["task"], result["seed"], result["split"]) == ("drawer", 0, "train")
    assert result["stop_reason"] == StopReason.TARGET_REACHED
    assert result["axis"]["joint_type"] == "prismatic"
    assert 0.05 <= result["true_opened_m"] <= 0.05 + 0.02  # reached, at most a 1.5 cm overshoot past it
    assert result["axis_angle_error_deg"] < 2.0
