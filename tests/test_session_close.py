"""study.engine.execute.Session: a Dask cluster slow to close on a loaded machine costs no finished
study (its close timed out once at the end of a quick study run under load 10 on 2 cores, and the
study ended in a traceback with its results computed)."""
import asyncio

import pytest

from study.engine.execute import CLOSE_TIMEOUT_S, Session


class _Slow:
    def __init__(self, exc):
        self.exc, self.calls = exc, []

    def close(self, **kw):
        self.calls.append(kw)
        raise self.exc


@pytest.mark.parametrize("exc", [TimeoutError(), asyncio.CancelledError(), OSError("comm closed")])
def test_a_cluster_that_does_not_close_in_time_is_said_not_raised(exc):
    logs = []
    s = Session(log=logs.append)
    s._client, s._cluster = _Slow(RuntimeError("client gone")), _Slow(exc)
    s.close()
    assert s._client is None and s._cluster is None
    assert len(logs) == 2 and "the cluster did not close cleanly" in logs[1]
    assert "the client did not close cleanly (RuntimeError)" in logs[0]


def test_the_cluster_gets_a_longer_close_than_dask_s_default():
    s, slow = Session(log=lambda m: None), _Slow(TimeoutError())
    s._cluster = slow
    s.close()
    assert slow.calls == [{"timeout": CLOSE_TIMEOUT_S}] and CLOSE_TIMEOUT_S > 30
