"""Point queries (irradiance, radiance) and quadratures against the raw HTTP
answers of a real service, and the splitting of large point sets."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from bmc_irradiance import Chunk, Client, ErrorTarget, ServiceError, chunk_seed
from conftest import Server, raw


def floor_points(count: int, seed: int = 0) -> np.ndarray:
    """Points just above the Cornell box's floor (y = -1), all different and
    none under the two boxes (whose footprints are within 0.45 of their centres)."""
    rng = np.random.default_rng(seed)
    xz = rng.uniform(-0.9, 0.9, (3 * count + 16, 2))
    for centre in ([0.335, 0.38], [-0.33, -0.28]):
        xz = xz[np.linalg.norm(xz - centre, axis=1) > 0.45]
    xz = xz[:count]
    assert len(xz) == count
    return np.column_stack([xz[:, 0], np.full(count, -0.999), xz[:, 1]])


def point_docs(positions: np.ndarray, normals: np.ndarray) -> list[dict[str, Any]]:
    return [{"position": p, "normal": n} for p, n in zip(positions.tolist(), normals.tolist())]


UP = np.array([0.0, 1.0, 0.0])


def test_the_client_and_the_service_default_alike(client: Client, server: Server) -> None:
    """With no estimator, samples or seed, the client asks what the service
    answers to a request that names none: one default for both, in W/m²."""
    positions = floor_points(3, seed=4)
    result = client.irradiance("cornell-box", positions, UP)
    status, doc, _ = raw(
        f"{server.url}/v1/scenes/cornell-box/irradiance",
        "POST",
        {"points": point_docs(positions, np.tile(UP, (3, 1)))},
    )
    assert status == 200, doc
    assert doc["unit"] == "W/m²"
    assert np.array_equal(result.value, np.array(doc["irradiance"]))
    assert np.array_equal(result.std_dev, np.array(doc["std_dev"]))


@pytest.mark.parametrize("method", ["mc", "qmc", "bmc"])
def test_irradiance_equals_the_raw_response(client: Client, server: Server, method: str) -> None:
    positions = floor_points(5, seed=1)
    normals = np.tile(UP, (5, 1))
    result = client.irradiance("cornell-box", positions, UP, method=method, samples=32, seed=7)
    status, doc, _ = raw(
        f"{server.url}/v1/scenes/cornell-box/irradiance",
        "POST",
        {
            "points": point_docs(positions, normals),
            "estimator": {"method": method, "samples": 32},
            "seed": 7,
        },
    )
    assert status == 200, doc
    assert result.value.shape == (5, 3) and result.std_dev.shape == (5, 3)
    assert np.array_equal(result.value, np.array(doc["irradiance"]))
    assert np.array_equal(result.std_dev, np.array(doc["std_dev"]))
    assert result.value.sum() > 0
    # The client's request came first and calibrated the error bars; the
    # raw one found that work kept, so its rays are the points' alone.
    assert doc["amortised_rays"] == 0
    assert result.rays == doc["rays"] + result.amortised_rays
    assert result.decomposition == doc["decomposition"]
    assert result.prior == doc["prior"]
    assert result.calibration == doc.get("calibration")
    assert result.lengthscale == doc.get("lengthscale")
    assert result.noise == doc.get("noise")
    assert (result.lengthscale is not None) == (method == "bmc")
    assert result.chunks == (Chunk(0, 5, 7),)
    assert result.samples is None and result.target_met is None


def test_options_reach_the_service(client: Client) -> None:
    points = floor_points(3, seed=2)
    result = client.irradiance(
        "overcast",
        points + UP,
        UP,
        method="bmc",
        samples=16,
        decomposition="hemisphere",
        prior="none",
        calibrate=False,
        kernel={"kind": "matern52", "lengthscale": 0.5},
        max_depth=2,
    )
    assert result.decomposition == "hemisphere"
    assert result.prior == "none"
    assert result.calibration is None
    assert result.lengthscale == 0.5
    # `bmc` leans on records by default; none are held, so none served.
    assert result.records_prior_points == 0
    assert result.prior_used == ({},) * 3
    plain = client.irradiance(
        "overcast", points + UP, UP, method="bmc", samples=16, records_prior=False
    )
    assert plain.records_prior_points is None and plain.prior_used is None


def test_light_samples_reach_the_service(client: Client) -> None:
    # With direct light only, the answer is the light samples' alone: 16
    # directions with 64 light samples answer as 64 directions.
    positions = floor_points(3, seed=5)
    asked: dict[str, Any] = {
        "method": "qmc",
        "calibrate": False,
        "decomposition": "split",
        "max_depth": 1,
    }
    apart = client.irradiance("cornell-box", positions, UP, samples=16, light_samples=64, **asked)
    same = client.irradiance("cornell-box", positions, UP, samples=64, **asked)
    assert np.array_equal(apart.value, same.value)
    with pytest.raises(ServiceError) as refused:
        client.irradiance("cornell-box", positions, UP, samples=16, light_samples=0)
    assert refused.value.field == "estimator.light_samples"


def test_the_records_prior_is_asked_for_and_reported(client: Client) -> None:
    # No test renders tiles of this scene, so it holds no records: the option
    # reaches the service, which reports that it covered no point; asked of
    # "mc" it is refused by name.
    positions = floor_points(3, seed=4)
    result = client.irradiance(
        "cornell-box-xml", positions, UP, method="qmc", samples=16, records_prior=True
    )
    assert result.records_prior_points == 0
    assert result.prior_used == ({},) * 3
    with pytest.raises(ServiceError) as refused:
        client.irradiance("cornell-box", positions, UP, method="mc", records_prior=True)
    assert refused.value.field == "estimator.records_prior"


def test_target_arrays_equal_the_raw_response(client: Client, server: Server) -> None:
    positions = floor_points(4, seed=3)
    target = ErrorTarget(relative_error=0.05, confidence=0.9, max_samples=512)
    result = client.irradiance("cornell-box", positions, UP, method="mc", samples=32, target=target)
    status, doc, _ = raw(
        f"{server.url}/v1/scenes/cornell-box/irradiance",
        "POST",
        {
            "points": point_docs(positions, np.tile(UP, (4, 1))),
            "estimator": {"method": "mc", "samples": 32},
            "target": {"relative_error": 0.05, "confidence": 0.9, "max_samples": 512},
        },
    )
    assert status == 200, doc
    assert result.samples is not None and result.samples.dtype == np.int64
    assert result.relative_error is not None and result.target_met is not None
    assert result.target_met.dtype == np.bool_
    assert result.samples.tolist() == doc["samples"]
    assert result.relative_error.tolist() == doc["relative_error"]
    assert result.target_met.tolist() == doc["target_met"]
    assert np.array_equal(result.value, np.array(doc["irradiance"]))
    # A dict target is the same request.
    again = client.irradiance(
        "cornell-box",
        positions,
        UP,
        method="mc",
        samples=32,
        target={"relative_error": 0.05, "confidence": 0.9, "max_samples": 512},
    )
    assert np.array_equal(again.value, result.value)


def test_bmc_takes_a_target_with_the_records_prior(client: Client) -> None:
    target = ErrorTarget(0.05, max_samples=1024)
    result = client.irradiance(
        "cornell-box", floor_points(2), UP, method="bmc", samples=32, target=target
    )
    assert result.samples is not None and result.target_met is not None
    # Each batch is the 32 set directions and 32 fresh ones.
    assert all(s % 64 == 0 and 64 <= s <= 1024 for s in result.samples.tolist())
    # The records prior (bmc's default, here asked for) meets the batches'
    # mean once; it reports which points it covered.
    explicit = client.irradiance(
        "cornell-box",
        floor_points(2),
        UP,
        method="bmc",
        samples=32,
        records_prior=True,
        target=target,
    )
    assert explicit.records_prior_points is not None
    assert explicit.target_met is not None and len(explicit.target_met) == 2


def test_split_point_sets_keep_their_order(client: Client, server: Server) -> None:
    """Every chunk is exactly the raw answer for its points and seed, in
    order; the first chunk also equals the start of one big request, the
    others do not (the service seeds points by their index in a request)."""
    positions = floor_points(30, seed=4)
    small = Client(server.url, max_points=7)
    result = small.irradiance("cornell-box", positions, UP, method="mc", samples=16, seed=5)
    assert [(c.start, c.stop) for c in result.chunks] == [
        (0, 7),
        (7, 14),
        (14, 21),
        (21, 28),
        (28, 30),
    ]
    assert [c.seed for c in result.chunks] == [chunk_seed(5, i) for i in range(5)]
    assert result.chunks[0].seed == 5 and len({c.seed for c in result.chunks}) == 5
    url = f"{server.url}/v1/scenes/cornell-box/irradiance"
    rays = 0
    for chunk in result.chunks:
        part = positions[chunk.start : chunk.stop]
        status, doc, _ = raw(
            url,
            "POST",
            {
                "points": point_docs(part, np.tile(UP, (len(part), 1))),
                "estimator": {"method": "mc", "samples": 16},
                "seed": chunk.seed,
            },
        )
        assert status == 200, doc
        assert np.array_equal(result.value[chunk.start : chunk.stop], np.array(doc["irradiance"]))
        assert np.array_equal(result.std_dev[chunk.start : chunk.stop], np.array(doc["std_dev"]))
        assert doc["amortised_rays"] == 0
        rays += doc["rays"]
    assert result.rays == rays + result.amortised_rays
    whole = client.irradiance("cornell-box", positions, UP, method="mc", samples=16, seed=5)
    assert len(whole.chunks) == 1
    assert np.array_equal(result.value[:7], whole.value[:7])
    assert not np.array_equal(result.value[7:], whole.value[7:])
    # Reproducible for the same limits and seed.
    again = small.irradiance("cornell-box", positions, UP, method="mc", samples=16, seed=5)
    assert np.array_equal(again.value, result.value)


def test_split_results_are_equivalent_in_distribution(server: Server) -> None:
    """Split and whole requests differ in their random numbers only: their
    differences are within the reported standard errors."""
    rng = np.random.default_rng(6)
    positions = np.column_stack(
        [rng.uniform(-3, 3, 60), np.full(60, 0.001), rng.uniform(2.2, 3.5, 60)]
    )
    options: dict[str, Any] = dict(
        method="mc", samples=64, decomposition="hemisphere", max_depth=2, seed=11
    )
    whole = Client(server.url).irradiance("overcast", positions, UP, **options)
    split = Client(server.url, max_points=10).irradiance("overcast", positions, UP, **options)
    assert len(whole.chunks) == 1 and len(split.chunks) == 6
    assert not np.array_equal(whole.value[10:], split.value[10:])
    scale = np.sqrt(whole.std_dev**2 + split.std_dev**2)
    assert np.all(scale > 0)
    z = (whole.value - split.value) / scale
    assert 0.4 < np.mean(z**2) < 2.5, np.mean(z**2)
    assert np.max(np.abs(z)) < 6


def test_the_point_limit_is_learnt_from_the_service(small_server: Server) -> None:
    positions = floor_points(25, seed=7)
    client = Client(small_server.url)
    assert client.max_points == 65536
    result = client.irradiance("cornell-box", positions, UP, method="mc", samples=8)
    assert client.max_points == 10
    assert [(c.start, c.stop) for c in result.chunks] == [(0, 10), (10, 20), (20, 25)]
    told = Client(small_server.url, max_points=10).irradiance(
        "cornell-box", positions, UP, method="mc", samples=8
    )
    assert np.array_equal(result.value, told.value)


def test_the_work_budget_is_learnt_from_the_service(small_server: Server) -> None:
    # small_server allows 1000 estimated paths per request: 10 points × 128
    # samples are refused (422 estimated_paths), 7 × 128 fit.
    positions = floor_points(10, seed=8)
    client = Client(small_server.url)
    result = client.irradiance("cornell-box", positions, UP, method="mc", samples=128)
    assert client.max_paths_per_request == 1000
    assert [(c.start, c.stop) for c in result.chunks] == [(0, 7), (7, 10)]
    assert np.all(result.value > 0)


def test_the_body_limit_is_learnt_from_the_service(tiny_body_server: Server) -> None:
    # tiny_body_server takes bodies of at most 1024 bytes: 12 points are
    # refused with 413 until the client's assumed limit is small enough.
    positions = floor_points(12, seed=10)
    client = Client(tiny_body_server.url)
    result = client.irradiance("cornell-box", positions, UP, method="mc", samples=4)
    # Lowered below the first refused body; each request then fitted.
    assert client.max_body_bytes < 2048
    assert len(result.chunks) >= 2
    assert result.chunks[-1].stop == 12
    told = Client(tiny_body_server.url, max_body_bytes=client.max_body_bytes)
    again = told.irradiance("cornell-box", positions, UP, method="mc", samples=4)
    assert again.chunks == result.chunks and np.array_equal(again.value, result.value)
    assert np.all(result.value > 0)


def test_a_hundred_thousand_points_come_back_in_order(client: Client, server: Server) -> None:
    positions = floor_points(100_000, seed=9)
    result = client.irradiance(
        "cornell-box", positions, UP, method="mc", samples=1, max_depth=1, seed=3
    )
    assert result.value.shape == (100_000, 3)
    chunks = result.chunks
    assert len(chunks) >= 2
    assert chunks[0].start == 0 and chunks[-1].stop == 100_000
    assert all(a.stop == b.start for a, b in zip(chunks, chunks[1:]))
    # A middle chunk is exactly the raw answer for its points.
    chunk = chunks[len(chunks) // 2]
    part = positions[chunk.start : chunk.stop]
    status, doc, _ = raw(
        f"{server.url}/v1/scenes/cornell-box/irradiance",
        "POST",
        {
            "points": point_docs(part, np.tile(UP, (len(part), 1))),
            "estimator": {"method": "mc", "samples": 1},
            "max_depth": 1,
            "seed": chunk.seed,
        },
    )
    assert status == 200
    assert np.array_equal(result.value[chunk.start : chunk.stop], np.array(doc["irradiance"]))


def test_point_errors_name_the_callers_index(server: Server) -> None:
    normals = np.tile(UP, (12, 1))
    normals[9] = 0.0
    client = Client(server.url, max_points=4)
    with pytest.raises(ServiceError) as caught:
        client.irradiance("cornell-box", floor_points(12), normals, method="mc")
    assert (caught.value.status, caught.value.code) == (422, "invalid_field")
    assert caught.value.field == "points[9].normal"


def test_bad_arrays_are_refused_before_sending(client: Client) -> None:
    with pytest.raises(ValueError):
        client.irradiance("cornell-box", [[0, 0, np.nan]], UP)
    with pytest.raises(ValueError):
        client.irradiance("cornell-box", [[0, 0]], UP)
    with pytest.raises(ValueError):
        client.irradiance("cornell-box", np.zeros((2, 2, 3)), UP)
    with pytest.raises(ValueError):
        client.irradiance("cornell-box", floor_points(3), np.tile(UP, (2, 1)))


def test_unknown_scenes_and_too_many_samples_are_typed_errors(client: Client) -> None:
    with pytest.raises(ServiceError) as caught:
        client.irradiance("no-such-scene", floor_points(1), UP)
    assert (caught.value.status, caught.value.code, caught.value.field) == (404, "not_found", None)
    with pytest.raises(ServiceError) as caught:
        client.irradiance("cornell-box", floor_points(1), UP, method="mc", samples=5000)
    err = caught.value
    assert (err.status, err.code, err.field) == (422, "limit_exceeded", "estimator.samples")


def test_radiance_equals_the_raw_response(client: Client, server: Server) -> None:
    positions = np.array([[0.0, -1.0, 0.0], [0.5, -1.0, -0.5], [0.0, 0.0, -1.0]])
    normals = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    directions = np.array([[0.0, 1.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.2, 1.0]])
    options: dict[str, Any] = dict(estimator="path", repeats=8, max_depth=8, seed=2)
    result = Client(server.url, max_points=2).radiance(
        "cornell-box", positions, normals, directions, **options
    )
    assert [(c.start, c.stop) for c in result.chunks] == [(0, 2), (2, 3)]
    url = f"{server.url}/v1/scenes/cornell-box/radiance"
    for chunk in result.chunks:
        status, doc, _ = raw(
            url,
            "POST",
            {
                "points": [
                    {"position": p, "normal": n, "direction": d}
                    for p, n, d in zip(
                        positions[chunk.start : chunk.stop].tolist(),
                        normals[chunk.start : chunk.stop].tolist(),
                        directions[chunk.start : chunk.stop].tolist(),
                    )
                ],
                "estimator": {"method": "path"},
                "repeats": 8,
                "max_depth": 8,
                "seed": chunk.seed,
            },
        )
        assert status == 200, doc
        assert np.array_equal(result.value[chunk.start : chunk.stop], np.array(doc["radiance"]))
        assert np.array_equal(result.std_dev[chunk.start : chunk.stop], np.array(doc["std_dev"]))
    assert np.all(result.value > 0)
    one = client.radiance("cornell-box", positions[:1], normals[0], directions[0], **options)
    assert np.array_equal(one.value, result.value[:1])


def test_quadrature_arrays_equal_the_raw_response(client: Client, server: Server) -> None:
    quadrature = client.quadrature(
        32, sample_set="fibonacci", kernel="squared_exponential", lengthscale=0.7, noise=1e-6
    )
    status, doc, _ = raw(
        f"{server.url}/v1/quadratures",
        "POST",
        {
            "sample_set": {"kind": "fibonacci", "count": 32},
            "kernel": {"kind": "squared_exponential", "lengthscale": 0.7, "noise": 1e-6},
            "density": {"kind": "lambert"},
        },
    )
    assert status == 200, doc
    assert doc["cached"] is True  # the client's request computed it
    assert quadrature.id == doc["id"]
    assert quadrature.directions.shape == (32, 3)
    assert np.array_equal(quadrature.directions, np.array(doc["directions"]))
    assert np.array_equal(quadrature.kernel_means, np.array(doc["kernel_means"]))
    assert np.array_equal(quadrature.weights, np.array(doc["weights"]))
    assert quadrature.posterior_variance == doc["posterior_variance"]
    assert quadrature.density_integral == doc["density_integral"]
    assert np.allclose(np.linalg.norm(quadrature.directions, axis=1), 1.0)
    assert quadrature.integrate(np.ones(32)) == pytest.approx(quadrature.weights.sum())
    with pytest.raises(ServiceError) as caught:
        client.quadrature(8, density="phong")
    assert (caught.value.code, caught.value.field) == ("invalid_field", "density.exponent")
