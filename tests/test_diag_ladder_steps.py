"""Stop 47: the ladder's steps. Named terms and references (``Term.reference``: structure reported ``unexplained``,
never named) each have their own number of steps, ``MismatchSearch.max_terms`` and ``max_references``: a reference
ranked first no longer takes a step a named term could have had. Until stop 46 both shared ``max_terms`` (4): on the
independent simulator's cases 0-179, 225 of the 328 diagnoses (cases and clean twins) ended with four terms; case
155's true cogging (every test passed from the first step) was never named, its four steps taken by a coupling and
three refits of the model's friction."""
import copy
import json

import numpy as np
import pytest

from diagnosis.library import Term
from diagnosis.residual import part_rows
from fixtures_diag import clean_model, recording


@pytest.fixture(scope="module")
def rd_clean():
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    return residual_data(load_model(clean_model()), read_log(recording(json.dumps([]))))


class _Known(Term):
    """A reference whose column on motor j is a slow sine of its own phase (what the test adds to the residual)."""
    kind, reference = "known_structure", True

    def motors(self, rd, j):
        return np.array([j])

    def columns(self, rd, j, h):
        col = np.zeros((len(rd.t), rd.n, 1))
        col[:, j, 0] = np.sin(2 * np.pi * 0.3 * rd.t + j)
        return col

    def effect(self, rd, j, h, coef, std):
        return {"kind": self.kind, "joints": [j]}, "known structure", True, ""


class _Named(_Known):
    """A named term, tried on joint 0 alone, whose column is a sine of another frequency."""
    kind, reference, per_joint = "named_structure", False, False

    def joints(self, rd):
        return [0]

    def columns(self, rd, j, h):
        col = np.zeros((len(rd.t), rd.n, 1))
        col[:, j, 0] = np.sin(2 * np.pi * 0.17 * rd.t)
        return col


def _with_structure(rd):
    """The clean recording's residual data with the references' structure on motors 2, 3, 4 (5 times each motor's
    RMS on the fit rows) and the named term's on motor 0 (twice its RMS): the references rank first."""
    rd = copy.copy(rd)
    m_fit = rd.mask & part_rows(rd.fit_rows, rd.n)
    res = np.nan_to_num(rd.residual)
    rms = np.array([np.sqrt(np.mean(res[m_fit[:, k], k] ** 2)) for k in range(rd.n)])
    rd.tau_meas, rd.tau_meas_raw = rd.tau_meas.copy(), rd.tau_meas_raw.copy()   # the measured torque, both bands
    for k, (term, size) in {0: (_Named(), 2.0), 2: (_Known(), 5.0), 3: (_Known(), 5.0), 4: (_Known(), 5.0)}.items():
        rd.tau_meas[:, k] += size * rms[k] * term.columns_low(rd, k, None)[:, k, 0]
        rd.tau_meas_raw[:, k] += size * rms[k] * term.columns(rd, k, None)[:, k, 0]
    rd.extra = dict(rd.extra)
    return rd


@pytest.mark.parametrize("max_references", [1, 3])
def test_a_reference_ranked_first_does_not_take_a_named_terms_step(rd_clean, max_references):
    from diagnosis.search import MismatchSearch

    rd = _with_structure(rd_clean)
    search = MismatchSearch(library=(_Known(), _Named()), max_terms=1, max_references=max_references).fit(rd)
    assert search.rankings_[0][0].term.reference                  # the ladder's first choice is a reference
    assert [(s.fitted.kind, s.fitted.joint) for s in search.accepted_] == [("named_structure", 0)]
    refs = [(s.fitted.kind, s.fitted.joint) for s in search.references_]
    assert len(refs) == max_references and {j for _, j in refs} <= {2, 3, 4}
    # one step per term; once the references are full they are not ranked again, and the ladder ends when both are
    assert len(search.rankings_) == 1 + max_references
    assert [s.fitted.kind for s in search.rankings_[-1]] == ["named_structure"]


def test_with_no_room_for_names_only_references_are_ranked(rd_clean):
    from diagnosis.search import MismatchSearch

    rd = _with_structure(rd_clean)
    search = MismatchSearch(library=(_Known(), _Named()), max_terms=0, max_references=2).fit(rd)
    assert search.accepted_ == [] and len(search.references_) == 2
    assert all(s.term.reference for step in search.rankings_ for s in step)
