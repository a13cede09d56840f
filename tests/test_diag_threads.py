"""The diagnosis runs its linear algebra on one BLAS thread, whatever the machine (diagnosis.run.diagnose)."""
from threadpoolctl import threadpool_info, threadpool_limits

import diagnosis.run as run


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_diagnose_runs_on_one_blas_thread_and_gives_the_others_back(monkeypatch):
    """Inside ``diagnose`` every BLAS library runs one thread (a multi-threaded BLAS sums in another order, and the
    independent simulator's case 213 named a joint elasticity with one OpenBLAS thread and nothing with two); the
    caller's setting is restored afterwards, also when the diagnosis raises."""
    seen = []

    def fake(model, log_path, options):
        seen.append(_blas_threads())
        if log_path == "bad":
            raise ValueError("bad log")
        return "result"

    monkeypatch.setattr(run, "_diagnose", fake)
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert run.diagnose("model", "log") == "result"
        try:
            run.diagnose("model", "bad")
        except ValueError:
            pass
        after = _blas_threads()
    assert seen and all(t and all(n == 1 for n in t) for t in seen)
    assert after == before
