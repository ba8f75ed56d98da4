"""Where benchmark episodes run: local worker processes (default) or a Ray cluster (`--ray ADDRESS`).

Every executor has the same `map(fn, jobs)`: `fn(**job)` for each job dict, results yielded **in job order**
(like the built-in `map`), each as soon as it and every job before it have finished, so a progress callback
advances steadily while later jobs are still running. A job that raises stops the map with a `JobError` naming
the job (`fn(**job)`, ready to rerun alone), chained to the original exception, or with the job's own
`ModelError` / `ConfigError` as it is (one line naming the thing, the cause and the fix); no further job starts
(local processes cancel the waiting ones; on Ray only two jobs per CPU are ever submitted ahead, since cancelling a
Ray task as it completes can crash the driver, and the few already running finish unused).
Use an executor as a context manager so a Ray connection is always shut down:

    with make_executor(workers=4, ray_address=None) as executor:
        for result in executor.map(simulate_episode, jobs): ...

`fn` and the jobs must be picklable (a module-level function and plain values); on a Ray cluster every node
needs axisloop installed (the same version), because `fn` is sent by reference.
"""

from __future__ import annotations

import logging
import socket
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from typing import Any, NoReturn, Protocol, TypeVar

from deploy.errors import ConfigError, JobError, ModelError

R = TypeVar("R")
RAY_INSTALL = "pip install 'axisloop[cluster]'"
RAY_CLIENT_PORT = 10001
CONNECT_TIMEOUT_S = 5.0
IN_FLIGHT_PER_CPU = 2  # Ray tasks submitted ahead per cluster CPU: enough to keep every CPU busy


class Executor(Protocol):
    """Runs `fn(**job)` for every job; results in job order; a context manager that releases its workers."""

    def __enter__(self) -> Executor: ...

    def __exit__(self, *exc_info: object) -> None: ...

    def map(self, fn: Callable[..., R], jobs: Iterable[dict[str, Any]]) -> Iterator[R]: ...


class LocalExecutor:
    """Jobs in this process when workers <= 1, else in a pool of `workers` processes (Python's default start
    method: fork on Linux; spawn on macOS, where a script calling this needs `if __name__ == "__main__":`)."""

    def __init__(self, workers: int = 1) -> None:
        self.workers = max(1, int(workers))

    def __enter__(self) -> LocalExecutor:
        return self

    def __exit__(self, *exc_info: object) -> None:
        """Nothing to release: each map's pool is closed when the map ends."""

    def map(self, fn: Callable[..., R], jobs: Iterable[dict[str, Any]]) -> Iterator[R]:
        jobs = list(jobs)
        if self.workers == 1:
            for index, job in enumerate(jobs):
                try:
                    yield fn(**job)
                except Exception as exc:
                    _raise_job_error(fn, index, len(jobs), job, exc, exc)
            return
        pool = ProcessPoolExecutor(min(self.workers, max(1, len(jobs))))
        try:
            futures = [pool.submit(_call, fn, job) for job in jobs]
            for index, (job, future) in enumerate(zip(jobs, futures, strict=True)):
                try:
                    result = future.result()
                except Exception as exc:
                    _raise_job_error(fn, index, len(jobs), job, exc, exc)
                yield result
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


class RayExecutor:
    """Jobs as Ray tasks of 1 CPU each, on the cluster at `address`:

    - "local": start a private Ray instance on this machine (`num_cpus` limits it; default all cores),
    - "auto": the cluster this machine belongs to (`ray start` was run here, or RAY_ADDRESS is set),
    - "ray://HOST:PORT": a remote cluster's Ray Client server (port 10001 by default),
    - "HOST:PORT": a cluster's GCS address, from a machine inside the cluster.

    Connects on entering (or on the first map) and shuts Ray down on exit, unless Ray was already initialised
    by the caller, whose connection is reused and left open.
    """

    def __init__(self, address: str = "local", num_cpus: int | None = None) -> None:
        _check_address(address, num_cpus)
        self.address = address
        self.num_cpus = num_cpus
        self._ray: Any = None
        self._owns_ray = False

    def __enter__(self) -> RayExecutor:
        self._connect()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Shut down the Ray connection (and the local instance) if this executor started it."""
        if self._ray is not None and self._owns_ray:
            self._ray.shutdown()
        self._ray, self._owns_ray = None, False

    def map(self, fn: Callable[..., R], jobs: Iterable[dict[str, Any]]) -> Iterator[R]:
        ray = self._connect()
        jobs = list(jobs)
        task = ray.remote(num_cpus=1)(_call)
        window = IN_FLIGHT_PER_CPU * max(1, int(ray.cluster_resources().get("CPU", 1)))
        refs = [task.remote(fn, job) for job in jobs[:window]]
        for index, job in enumerate(jobs):
            try:
                result = ray.get(refs[index])
            except ray.exceptions.RayTaskError as exc:
                _raise_job_error(fn, index, len(jobs), job, exc.cause or exc, exc)
            except ray.exceptions.RayError as exc:  # worker or node died, object lost
                _raise_job_error(fn, index, len(jobs), job, exc, exc)
            if index + window < len(jobs):
                refs.append(task.remote(fn, jobs[index + window]))
            yield result

    def _connect(self) -> Any:
        if self._ray is not None:
            return self._ray
        try:
            import ray
        except ImportError as exc:
            raise ConfigError(f"--ray {self.address}: Ray is not installed; install it with {RAY_INSTALL}, "
                              "or leave out --ray to run on local worker processes") from exc
        _check_reachable(self.address)
        if ray.is_initialized():
            self._ray, self._owns_ray = ray, False
            return ray
        options: dict[str, Any] = {"include_dashboard": False} if self.address == "local" else {}
        if self.num_cpus is not None:
            options["num_cpus"] = self.num_cpus
        try:
            ray.init(address=self.address, logging_level=logging.WARNING, **options)
        except ConnectionError as exc:
            if _chain_mentions(exc, "AuthenticationError", "InvalidAuthToken"):  # Ray nests it in a message
                raise ConfigError(f"--ray {self.address}: the Ray cluster refused the connection (no or wrong "
                                  "authentication token); set RAY_AUTH_MODE=token and give the cluster's token "
                                  "(~/.ray/auth_token or RAY_AUTH_TOKEN), see Ray's token-auth docs") from exc
            raise ConfigError(f"--ray {self.address}: cannot connect to the Ray cluster ({exc}); check that the "
                              "head node runs (`ray start --head`) and the address (ray://HOST:10001 or HOST:6379); "
                              "a cluster with token authentication also needs RAY_AUTH_MODE=token") from exc
        except ValueError as exc:
            if "ray[client]" not in str(exc):
                raise
            raise ConfigError(f"--ray {self.address}: Ray is installed without its client (needed for ray://); "
                              f"install it with {RAY_INSTALL}") from exc
        self._ray, self._owns_ray = ray, True
        return ray


def make_executor(workers: int = 1, ray_address: str | None = None) -> Executor:
    """A RayExecutor on `ray_address` when given (then `workers` is unused: Ray runs one job per cluster CPU),
    else a LocalExecutor with `workers` processes."""
    return LocalExecutor(workers) if ray_address is None else RayExecutor(ray_address)


PASSED_THROUGH = (ModelError, ConfigError)  # a user's one-line error, the same in every job: raised as it is


def _raise_job_error(fn: Callable[..., Any], index: int, total: int, job: dict[str, Any], exc: BaseException,
                     caught: BaseException) -> NoReturn:
    """Raise the job's own `ModelError` / `ConfigError` as it is (its message already names the thing, the cause
    and the fix), anything else as `_job_error(...)` chained to `caught` (what the executor caught)."""
    if isinstance(exc, PASSED_THROUGH):
        raise exc
    raise _job_error(fn, index, total, job, exc) from caught


def _job_error(fn: Callable[..., Any], index: int, total: int, job: dict[str, Any], exc: BaseException) -> JobError:
    """A JobError naming job `index` of `total` as a call that reproduces it, the cause and how to debug it."""
    call = f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', repr(fn))}"
    arguments = ", ".join(f"{key}={value!r}" for key, value in job.items())
    cause = " ".join(str(exc).split())  # one line, for the CLI's one red line
    error = JobError(f"job {index + 1} of {total} failed: {call}({arguments}) raised {type(exc).__name__}: "
                     f"{cause}; rerun that call alone in Python to see the full traceback")
    error.job = job
    return error


def _call(fn: Callable[..., R], job: dict[str, Any]) -> R:
    return fn(**job)


def _chain_mentions(exc: BaseException | None, *words: str) -> bool:
    """Whether a word is in the type name or message of `exc` or of any exception it was raised from."""
    while exc is not None:
        if any(word in f"{type(exc).__name__}: {exc}" for word in words):
            return True
        exc = exc.__cause__ or exc.__context__
    return False


def _check_address(address: str, num_cpus: int | None) -> None:
    if address not in ("local", "auto") and _host_port(address) is None:
        raise ConfigError(f"--ray {address!r}: not a Ray address; use local, auto, ray://HOST:PORT or HOST:PORT")
    if num_cpus is not None and (address != "local" or num_cpus < 1):
        raise ConfigError(f"num_cpus={num_cpus} with --ray {address}: a CPU count (>= 1) applies only to a "
                          "local instance (--ray local); a cluster's CPUs are set by `ray start --num-cpus`")


def _host_port(address: str) -> tuple[str, int] | None:
    """(host, port) of "ray://HOST[:PORT]" or "HOST:PORT", else None."""
    client = address.startswith("ray://")
    rest = address.removeprefix("ray://")
    host, sep, port = rest.rpartition(":")
    if not sep:
        host, port = rest, str(RAY_CLIENT_PORT) if client else ""
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        return None
    return host.strip("[]"), int(port)


def _check_reachable(address: str) -> None:
    """Fail in seconds, not minutes (Ray retries an unreachable cluster for a long time)."""
    host_port = _host_port(address) if address not in ("local", "auto") else None
    if host_port is None:
        return
    try:
        socket.create_connection(host_port, timeout=CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise ConfigError(f"--ray {address}: Ray cluster unreachable ({exc}); check the address, that the head "
                          "node runs (`ray start --head`) and that its port is open from here") from exc
