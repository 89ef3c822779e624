"""Running slopelander's work on a Dask cluster: connecting, checking the workers, warming them.

A worker must compute what this machine would, or nothing: :func:`prepare` registers a worker
plugin that compares each worker's slopelander (its version and a digest of its sources, which
decide every number) with this machine's and refuses a difference, then loads the compiled model
once per worker process, before any task needs it. Every task checks the digest again, so a
worker that joins later with another installation is refused too, not silently used.

:func:`gather` collects futures as they finish (a progress bar moves with them) and turns the
cluster's failures into a :class:`ClusterError` a user can act on. A task whose worker dies is
run again by the scheduler on another worker; each future is read once, so a result is never
counted twice. See docs/cluster.md.
"""

from __future__ import annotations

import asyncio
import functools
import hashlib
import weakref
from collections.abc import Callable, Sequence
from pathlib import Path

from slopelander.errors import SlopelanderError

WARM_UPS = ("batch", "landing")
"""What a worker can compile before its first task: the batch of landings (maps, the lookup
table) and the single sampled landing (comparisons, fits, diagnose)."""


class ClusterError(SlopelanderError):
    """The Dask cluster cannot do the work (unreachable, another slopelander, workers dying)."""


class ClusterVersionError(ClusterError):
    """A worker runs another slopelander than this machine: its numbers would differ."""


@functools.cache
def fingerprint() -> str:
    """This installation's slopelander: ``VERSION+DIGEST``, the digest over the package's
    sources and data files, so two installations of one version but different code (a local
    edit, another commit) are told apart as well."""
    import slopelander

    root = Path(slopelander.__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*")):
        if p.suffix in (".py", ".yaml", ".csv") and "__pycache__" not in p.parts:
            h.update(p.relative_to(root).as_posix().encode() + b"\0" + p.read_bytes() + b"\0")
    return f"{slopelander.__version__}+{h.hexdigest()[:12]}"


def check_worker(expected: str, where: str = "") -> None:
    """Refuse to compute on a worker whose slopelander is not the client's ``expected``."""
    mine = fingerprint()
    if mine == expected:
        return
    if not where:
        try:
            from distributed import get_worker

            where = get_worker().address
        except ValueError:
            where = "this process"
    v_mine, _, d_mine = mine.partition("+")
    v_exp, _, d_exp = expected.partition("+")
    if v_mine != v_exp:
        what = f"slopelander {v_mine}, the client {v_exp}"
    else:
        what = f"slopelander {v_mine} with other sources (digest {d_mine}, the client's {d_exp})"
    raise ClusterVersionError(
        f"the Dask worker at {where} runs {what}: its results would not be this machine's; "
        f"install the same slopelander on every worker (pip install 'slopelander[cluster]=={v_exp}', "
        "or the same checkout), then restart the workers"
    )


def warm_up(what: Sequence[str]) -> None:
    """Compile (or load from numba's cache) the model's entry points named in ``what``."""
    from slopelander.model import LandingConditions, Model, simulate, simulate_batch

    model = Model.default()
    if "batch" in what:
        simulate_batch([LandingConditions()], model)
    if "landing" in what:
        simulate(LandingConditions(), model)


try:
    from distributed import WorkerPlugin
except ImportError:  # pragma: no cover - the cluster extra installs it
    WorkerPlugin = object  # type: ignore[assignment,misc]


class SlopelanderWorker(WorkerPlugin):
    """Set up on every worker, now and joining later: the version check, then the warm-up."""

    name = "slopelander"

    def __init__(self, expected: str, warm: Sequence[str]) -> None:
        self.expected = expected
        self.warm = tuple(warm)

    async def setup(self, worker) -> None:
        check_worker(self.expected, worker.address)
        # in a thread: a first compile takes a minute, and the worker must keep answering the
        # scheduler meanwhile
        await asyncio.to_thread(warm_up, self.warm)


_PREPARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Per client, what its workers were warmed up for (a sweep is many calls: do it once)."""


def connect(address: str, timeout: str = "10s"):
    """A Dask client for ``address`` (``tcp://host:8786``), or a clear error."""
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - the test extra installs it
        raise ClusterError("--dask needs dask[distributed]: pip install 'slopelander[cluster]'") from None
    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: {exc}") from None


def prepare(client, warm: Sequence[str], wait: float = 60.0) -> None:
    """Check every worker's slopelander and warm it up for ``warm`` (see :data:`WARM_UPS`);
    waits until that is done on every worker, once per client and kind of work. A cluster
    without workers is given ``wait`` seconds to get one, then refused (not waited on for ever)."""
    done = _PREPARED.setdefault(client, set())
    if set(warm) <= done:
        return
    if not client.nthreads():
        try:
            client.wait_for_workers(1, timeout=wait)
        except TimeoutError:
            raise ClusterError(
                f"the Dask scheduler at {client.scheduler.address} has no workers (waited {wait:g} s): "
                f"start them with 'dask worker {client.scheduler.address}' (docs/cluster.md)"
            ) from None
    plugin = SlopelanderWorker(fingerprint(), sorted(done | set(warm)))
    try:
        client.register_plugin(plugin, name="slopelander")
    except ClusterError:
        raise
    except Exception as exc:  # a worker without slopelander, or one too old to know the plugin
        raise ClusterError(
            f"a Dask worker could not take slopelander's setup ({type(exc).__name__}: {exc}); "
            "install the same slopelander on every worker: pip install 'slopelander[cluster]'"
        ) from None
    done.update(warm)


def threads(client) -> int:
    """Task slots on the cluster now (one a worker thread); at least 1."""
    return max(1, sum(client.nthreads().values()))


def slots(client) -> list[str]:
    """The workers' addresses, each as many times as it has threads: where to send a batch's
    tasks, one a thread, when they all need the same data (the scheduler would otherwise keep
    them on the worker that holds it)."""
    return [a for a, n in sorted(client.nthreads().items()) for _ in range(n)]


def gather(futures: Sequence, on_done: Callable[[int, object], None]) -> None:
    """Call ``on_done(index, result)`` for every future, in the order they finish; on any
    failure the remaining futures are cancelled (Ctrl-C included) and a task's error is raised
    (as a :class:`ClusterError` when the cluster, not the work, failed)."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    index = {f.key: i for i, f in enumerate(futures)}
    finished = False
    try:
        # the futures' own client's loop: as_completed would take the default client's, another
        # one's when a program holds two clients
        loop = futures[0].client.loop if futures else None
        for f in as_completed(futures, loop=loop):
            try:
                result = f.result()
            except KilledWorker as exc:
                raise ClusterError(
                    f"a task killed every worker it ran on ({exc}): it needs more memory than a "
                    "worker has, or the workers are being stopped; see docs/cluster.md"
                ) from None
            except FutureCancelledError as exc:
                why = " ".join(str(exc).split())
                raise ClusterError(
                    f"the Dask scheduler dropped the work ({why}): is it still running?"
                ) from None
            on_done(index[f.key], result)  # each future is yielded once: never counted twice
        finished = True
    finally:
        if not finished:
            client = futures[0].client if futures else None
            if client is not None and client.status == "running":
                client.cancel(list(futures))
