"""Bitten hyper-ellipsoid, regularised covariance, classifier order (paper 5.2, 5.3)."""

import numpy as np
from conftest import ring
from stns_core.classifier import Classifier
from stns_core.situation import R_KIND, Situation, regularised_cov


def situation_over(points, neg_points=(), sid=1):
    pts = np.vstack([points] + ([np.atleast_2d(neg_points)] if len(neg_points) else []))
    sit = Situation(sid, R_KIND, 0, len(pts), 2, reward_key=10.0)
    sit.pos[: len(points)] = True
    sit.neg[len(points):] = True
    sit.fit(pts, 1e-3)
    return sit, pts


def test_boundary_is_the_farthest_positive_instance():
    pts = np.array([[0.0, 0.0], [1.0, 0.5], [-1.0, 0.2], [0.3, -1.0], [4.0, 4.0]])
    sit, x = situation_over(pts)
    d = np.sqrt(sit.mahalanobis2(pts))
    assert np.isclose(sit.boundary, d.max())
    assert all(sit.accepts(p, x) for p in pts)  # the farthest itself is inside
    assert not sit.accepts(pts[4] * 1.05, x)


def test_negative_instance_bites_a_hole_the_ellipsoid_would_not():
    positives = ring((0.0, 0.0), radius=3.0, n=12)
    probe = np.array([0.3, 0.0])
    whole, x0 = situation_over(positives)
    assert whole.mahalanobis2(probe)[0] <= whole.boundary2()
    assert whole.accepts(probe, x0)  # ellipsoid and nearest neighbour both accept
    bitten, x1 = situation_over(positives, neg_points=[[0.0, 0.0]])
    assert bitten.mahalanobis2(probe)[0] <= bitten.boundary2()  # still inside the ellipsoid
    assert not bitten.accepts(probe, x1)  # but the negative instance is nearer: a hole
    assert bitten.accepts(np.array([2.5, 0.0]), x1)  # the rest of the situation is intact


def test_nearest_neighbour_axes_scaled_by_positive_std():
    # positives spread 10x wider along x than y; negative at distance 1 along x, positive
    # at distance 0.6 along y: Euclidean says positive, std-scaled says negative.
    pos = np.array([[-10.0, -1.0], [10.0, 1.0], [-10.0, 1.0], [10.0, -1.0], [0.0, 0.6]])
    sit, x = situation_over(pos, neg_points=[[1.0, 0.0]])
    assert not sit.accepts(np.array([0.0, 0.0]), x)


def test_regularised_covariance_never_singular():
    collinear = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]])
    for pts in (collinear, collinear[:1], np.zeros((5, 2)), np.ones((3, 8))):
        cov = regularised_cov(pts, 1e-3)
        assert np.all(np.linalg.eigvalsh(cov) > 0)
        np.linalg.cholesky(cov)
    sit, x = situation_over(collinear)
    assert sit.accepts(np.array([1.5, 1.5]), x)
    assert not sit.accepts(np.array([1.5, -1.5]), x)


def test_classifier_first_acceptance_wins_and_margin_is_zero():
    a, _ = situation_over(ring((0.0, 0.0)), sid=1)
    b, _ = situation_over(ring((2.0, 0.0)), sid=2)
    x = np.vstack([ring((0.0, 0.0)), ring((2.0, 0.0))])
    a.pos = np.r_[np.ones(8, bool), np.zeros(8, bool)]
    a.neg = np.zeros(16, bool)
    b.pos = ~a.pos
    b.neg = np.zeros(16, bool)
    a.fit(x, 1e-3)
    b.fit(x, 1e-3)
    clf = Classifier(2)
    clf.order[:] = [a, b]
    overlap = np.array([1.0, 0.0])
    assert clf.classify(overlap, x) == 1
    clf.order[:] = [b, a]
    clf.invalidate()
    assert clf.classify(overlap, x) == 2
    assert clf.classify(np.array([50.0, 50.0]), x) == 0
    batch = clf.classify_batch(np.array([overlap, [50.0, 50.0], [-1.5, 0.0]]), x)
    assert batch.tolist() == [2, 0, 1]
