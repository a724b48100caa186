"""``sunlab info CAL.json`` (sunlab.calibration.summary): the text says each method's size, the
domain, the training and validation errors and the provenance, from the document alone."""

import json

import numpy as np

from sunlab import sim
from sunlab.calibration import Interpolation, Polynomial
from sunlab.calibration.summary import calibration_summary

DOC = {"sunlab_schema": "calibration/1", "kind": "polynomial", "label": "polynomial(3)",
       "sunlab_version": "0.1.0", "created": "2026-01-01T00:00:00Z",
       "parameters": {"order": [3, 4]},
       "training": {"experiment": "I", "n_poses": 400, "n_shots": 8, "n_ok_shots": 3199},
       "domain": {"alpha": [-17, 2], "beta": [-2, 17], "x": [10, 700], "y": [5, 690]},
       "residuals": {"alpha": {"mean_abs": 0.007, "rms": 0.009, "max_abs": 0.02},
                     "beta": {"mean_abs": 0.008, "rms": 0.01, "max_abs": 0.03},
                     "validation": None}}


def test_every_part_of_a_document_is_said():
    lines = calibration_summary(DOC).splitlines()
    assert lines[0] == "calibration/1: polynomial(3) (kind 'polynomial'), orders alpha 3, beta 4"
    assert lines[1] == ("  domain: alpha [-17, 2] deg, beta [-2, 17] deg; centroid x [10, 700] "
                        "px, y [5, 690] px")
    assert "400 poses x 8 shots (3199 ok)" in lines[2]
    assert lines[3] == ("  training residuals (deg): alpha mean|e| 0.00700, rms 0.00900, max "
                        "0.02000; beta mean|e| 0.00800, rms 0.01000, max 0.03000")
    assert lines[4] == "  validation errors (deg): none (fitted without a validation table)"
    assert lines[5] == "  written by sunlab 0.1.0, created 2026-01-01T00:00:00Z"


def test_a_sparse_document_says_what_is_missing_instead_of_failing():
    text = calibration_summary({"kind": "optimised", "parameters": {}})
    assert text.splitlines()[0] == ("?: optimised (kind 'optimised'), dF n/a mm, alpha0 n/a deg, "
                                    "beta0 n/a deg")
    assert "alpha [n/a, n/a] deg" in text and "mean|e| n/a" in text


def test_a_fitted_calibrations_own_summary_matches_its_saved_document():
    a, b = np.meshgrid(np.arange(-4.0, 4.1), np.arange(-4.0, 4.1))
    train = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2)
    cal = Polynomial(order=3).fit(train, train)
    doc = json.loads(json.dumps(cal.to_dict()))
    text = calibration_summary(doc)
    assert text == cal.summary()
    assert "order 3" in text.splitlines()[0] and "validation errors (deg): alpha" in text


def test_an_interpolation_reports_its_leave_one_out_errors():
    a, b = np.meshgrid(np.arange(-3.0, 3.1, 2.0), np.arange(-3.0, 3.1, 2.0))
    cal = Interpolation("linear").fit(sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1))
    text = calibration_summary(cal.to_dict())
    assert "16 nodes" in text and "~0 by construction" in text
    assert "leave-one-out errors (deg): alpha mean|e| " in text
