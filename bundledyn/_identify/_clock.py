"""Where a fit's time goes: JAX's compiling apart from the sections that compute."""

import contextlib
import contextvars
import time

import jax

__all__ = ["FitClock"]

# JAX's events for the three phases of making a program: tracing to a jaxpr, lowering it
# to XLA and XLA's compiling (a program found in the cache sends none of them).
_COMPILE_EVENTS = frozenset(
    {
        "/jax/core/compile/jaxpr_trace_duration",
        "/jax/core/compile/jaxpr_to_mlir_module_duration",
        "/jax/core/compile/backend_compile_duration",
    }
)
_RUNNING: contextvars.ContextVar["FitClock | None"] = contextvars.ContextVar(
    "bundledyn_fit_clock", default=None
)
_LISTENING = [False]


def _on_event(event: str, duration_secs: float, **kwargs: str | int) -> None:
    clock = _RUNNING.get()
    if clock is not None and event in _COMPILE_EVENTS:
        clock.compile_seconds += duration_secs


class FitClock:
    """A fit's wall time, split into JAX's compiling and named sections of computing.

    While it runs (`with clock:`), every program JAX traces, lowers or compiles in this
    context adds its time to `compile_seconds`; `section(name)` adds the wall time of its
    block, less the compiling inside it, to `seconds[name]`. The listener is JAX's
    (`jax.monitoring`), registered once per process and silent outside a running clock.
    """

    def __init__(self):
        self.compile_seconds = 0.0
        self.seconds: dict[str, float] = {}
        self._begin = 0.0
        self._token = None
        if not _LISTENING[0]:
            jax.monitoring.register_event_duration_secs_listener(_on_event)
            _LISTENING[0] = True

    def __enter__(self) -> "FitClock":
        self._begin = time.perf_counter()
        self._token = _RUNNING.set(self)
        return self

    def __exit__(self, *exc) -> None:
        assert self._token is not None
        _RUNNING.reset(self._token)
        self.seconds["total"] = time.perf_counter() - self._begin

    def elapsed(self) -> float:
        """Seconds since the clock started."""
        return time.perf_counter() - self._begin

    @contextlib.contextmanager
    def section(self, name: str):
        """Add the block's wall time, less JAX's compiling in it, to `seconds[name]`."""
        begin, compiled = time.perf_counter(), self.compile_seconds
        try:
            yield
        finally:
            spent = time.perf_counter() - begin - (self.compile_seconds - compiled)
            self.seconds[name] = self.seconds.get(name, 0.0) + spent
