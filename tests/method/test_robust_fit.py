"""The robust fit: solvers, weights, stopping, fall-backs, the output blend."""
import numpy as np
import pytest
from shadowflow.nodes.geometry.normals import angle_deg
from shadowflow.nodes.geometry.reflectance import lambertian, light_from_angles
from shadowflow.nodes.method.robust_fit import FitConfig, combine, fit, huber_weights, residual_scale
from shadowflow.nodes.model.sources import procedural


def _fit_errors(model, depths, light, configs: dict) -> dict:
    """Mean angular error (degrees) of the combined normals and the iterations, per config name."""
    from shadowflow.nodes.evaluation.scenes import render_scene
    from shadowflow.nodes.method.robust_fit import initial_normals

    out = {name: {"err": [], "iterations": []} for name in configs}
    for d in depths:
        sc = render_scene(d, 1.0, light, model.mask)
        ok = sc.valid[model.mask]
        for name, cfg in configs.items():
            r = fit(model, sc.image[model.mask], light, cfg, initial_normals(model, sc.image, light, cfg))
            n = combine(r.normals, r.model_normals, r.weights)
            out[name]["err"].append(float(np.mean(angle_deg(n[ok], sc.normals[model.mask][ok]))))
            out[name]["iterations"].append(r.iterations)
    return out


def test_huber_weights_and_scales():
    r = np.array([0.0, 0.5, 1.0, 2.0, 4.0])
    np.testing.assert_allclose(huber_weights(r, 1.0), [1, 1, 1, 0.5, 0.25])
    rng = np.random.default_rng(0)
    eta = np.linalg.norm(rng.normal(0, 0.1, (200_000, 2)), axis=1)  # 2-D residuals, sigma 0.1 per axis
    assert residual_scale(eta, "rayleigh") == pytest.approx(0.1, rel=0.01)
    # the paper's MAD of the norm lands well below the per-axis sigma
    assert residual_scale(eta, "mad") < 0.08


def test_fit_recovers_an_in_model_face_through_a_cast_shadow(procedural_model):
    """A face IN the model's span, with a square 'cast shadow' painted on the lit side: the
    robust fit must fill it in from the model and leave the lit pixels on their cones."""
    m = procedural_model
    rng = np.random.default_rng(5)
    b_true = rng.standard_normal(m.n_modes) * np.sqrt(m.eigenvalues) * 0.8
    n_true = m.synthesize(b_true)
    s = light_from_angles(30)
    img = m.to_image(lambertian(n_true, s), fill=0.0)
    occluded = np.zeros(m.grid, bool)
    occluded[60:80, 70:90] = True
    img[occluded] = 0.0
    I = img[m.mask]
    res = fit(m, I, s, FitConfig(albedo_rounds=0))  # one albedo: the lit pixels' cones are the image's own
    n = combine(res.normals, res.model_normals, res.weights)
    occ = occluded[m.mask]
    assert res.converged
    assert np.mean(angle_deg(n, n_true)) < 1.0
    assert np.mean(angle_deg(n[occ], n_true[occ])) < 2.0
    assert np.mean(res.weights[occ] < 0.5) > 0.5 or np.mean(res.weights[occ] == 0) > 0.5
    lit = ~occ & (I > 0.05)
    np.testing.assert_allclose(res.normals[lit] @ s, I[lit], atol=1e-6)


@pytest.mark.slow
def test_gauss_newton_reaches_the_alternations_answer_in_fewer_iterations(procedural_model):
    """The Gauss-Newton steps and the paper's alternation have the same fixed point (equal
    gradient); the steps that ignore motion along the cones get there in far fewer iterations,
    while the alternation creeps and stops (change < 0.01 deg per iteration) short of it.
    Measured on these faces with the defaults tuned for photos (prior 300, Huber 1.0, one albedo
    round): 45 deg: errors 0.37 vs 0.43 deg, 10 vs 36 iterations; 70 deg: 0.55 vs 1.00 deg, 14 vs
    85 iterations (before that tuning: 0.28 / 0.39 deg in 10 / 12 iterations)."""
    depths, _ = procedural(4, seed=7)
    for angle in (45, 70):
        res = _fit_errors(procedural_model, depths, light_from_angles(angle),
                          {"gn": FitConfig(), "irls": FitConfig(solver="irls")})
        gn, alt = res["gn"], res["irls"]
        assert np.all(np.subtract(gn["err"], alt["err"]) < 0.02), (angle, res)  # as good on every face
        assert np.mean(gn["err"]) < 0.7, (angle, res)
        assert np.mean(gn["iterations"]) < 0.5 * np.mean(alt["iterations"]), (angle, res)


@pytest.mark.slow
def test_exact_irls_beats_the_papers_one_step_formula(procedural_model):
    """The same alternation, every other choice the paper's: the exact weighted least squares per
    pass against the one-step formula (3). Measured at 60 deg: 5.0 against 12.0 deg; IRLS with
    today's defaults 0.58 deg (Gauss-Newton 0.41)."""
    depths, _ = procedural(4, seed=7)
    res = _fit_errors(procedural_model, depths, light_from_angles(60),
                      {"irls": FitConfig.paper(solver="irls"), "paper": FitConfig.paper(),
                       "irls_defaults": FitConfig(solver="irls")})
    assert np.mean(res["irls"]["err"]) < 0.5 * np.mean(res["paper"]["err"]), res
    assert np.mean(res["irls_defaults"]["err"]) < 1.0, res


def test_fit_config_is_checked_where_it_is_built():
    """An unknown solver or an impossible option fails at once, naming the option (it used to fail
    at iteration 2, or with UnboundLocalError for max_iterations=0)."""
    for bad, field in [({"solver": "newton"}, "solver"), ({"max_iterations": 0}, "max_iterations"),
                       ({"scale": "std"}, "scale"), ({"huber_k": 0.0}, "huber_k"), ({"cone_trust": 1.5}, "cone_trust"),
                       ({"relaxation": 2.0}, "relaxation"), ({"albedo_rounds": -1}, "albedo_rounds"),
                       ({"n_modes": 0}, "n_modes"), ({"init": "zero"}, "init")]:
        with pytest.raises(ValueError, match=f"FitConfig.{field}"):
            FitConfig(**bad)
    assert FitConfig.paper().stop_tolerance_deg == 0.01 and FitConfig().stop_tolerance_deg == 0.1


def test_iteration_records_are_complete(procedural_model):
    m = procedural_model
    s = light_from_angles(45)
    I = np.clip(m.mean_normals @ s, 0, 1)
    seen = []
    res = fit(m, I, s, FitConfig(max_iterations=7, tolerance_deg=0.0), on_iteration=seen.append)
    assert [r.iteration for r in seen] == list(range(1, 8)) and res.iterations == 7 and not res.converged
    for r in seen:
        assert r.normals.shape == (m.n_pixels, 3) and r.weights.shape == (m.n_pixels,)
        assert r.residuals.shape == (m.n_pixels,) and r.b.shape == (m.n_modes,)
        assert np.all((r.weights >= 0) & (r.weights <= 1))
    assert len(res.history) == 7 and res.history[-1]["change_deg"] == pytest.approx(seen[-1].change_deg)


def test_combine_blends_by_weight_and_keeps_normals_visible():
    a = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.6, 0.0, -0.8]])
    b = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.6, 0.0, -0.8]])
    out = combine(a, b, np.array([1.0, 0.5, 1.0]))
    np.testing.assert_allclose(out[0], [0, 0, 1])
    np.testing.assert_allclose(out[1], [np.sqrt(0.5), 0, np.sqrt(0.5)])
    assert out[2, 2] > 0 and out[2, 0] > 0.99  # faced away: moved to the silhouette, same azimuth
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1)


def test_saturated_pixels_do_not_bend_the_shape(procedural_model):
    """An over-exposed photo (brightness x1.8, clipped): the scale from unclipped pixels and
    no constraint from clipped ones (2.1 deg) must beat taking them at face value (16.4 deg)."""
    import dataclasses

    from shadowflow.flow.chain import Chain
    from shadowflow.nodes.evaluation.scenes import render_scene
    from shadowflow.nodes.evaluation.synthetic import score
    from shadowflow.nodes.method.nodes import method_nodes, on_model_grid
    from shadowflow.nodes.method.options import MethodOptions

    depths, _ = procedural(4, seed=21)
    s = light_from_angles(30, 0)
    errors = {}
    for name, saturation in (("excluded", 0.99), ("trusted", 2.0)):
        opts = MethodOptions(fit=dataclasses.replace(FitConfig(), saturation=saturation))
        chain = Chain(method_nodes(opts, with_views=False))
        errs = []
        for i, d in enumerate(depths):
            scene = render_scene(d, 1.0, s, procedural_model.mask)
            image = np.clip(scene.image * 1.8, 0, 1).astype(np.float32)
            assert np.mean(image[procedural_model.mask] >= 0.99) > 0.2
            frame = chain.process(on_model_grid(i, "overexposed", image, s, procedural_model))
            errs.append(score(scene, frame)["err_all"])
        errors[name] = float(np.mean(errs))
    assert errors["excluded"] < 0.5 * errors["trusted"], errors
    assert errors["excluded"] < 5.0, errors


def test_first_pass_shortcut_equals_theweighted_solve(procedural_model):
    """With unit weights the Gram matrix of orthonormal modes is I minus the released rows'
    part: the shortcut must give the weighted least squares' coefficients."""
    from shadowflow.nodes.method.robust_fit.linalg import unit_weight_solve, weighted_solve

    m = procedural_model
    P32 = m.modes_as(np.float32)
    rng = np.random.default_rng(3)
    r0 = rng.normal(0.0, 0.2, 2 * m.n_pixels)
    for fraction in (0.0, 0.1, 0.4):
        released = rng.random(m.n_pixels) < fraction
        w2 = np.repeat(np.where(released, 0.0, 1.0), 2)
        exact = weighted_solve(P32, np.empty_like(P32), w2, r0, np.zeros(m.n_modes))
        np.testing.assert_allclose(unit_weight_solve(P32, released, r0), exact, rtol=1e-4, atol=1e-5)


@pytest.mark.slow
def test_a_diverging_gauss_newton_step_falls_back_to_the_alternation(procedural_model, monkeypatch):
    """Steps three times too long blow the residual scale up; the fit must notice, continue by the
    alternation (which cannot diverge) and end near its answer. Measured: 0.37 / 0.26 deg against
    the alternation's 0.31 / 0.23, in 44-55 iterations; without the fallback 58 deg after 100."""
    from shadowflow.nodes.method.robust_fit import loop

    depths, _ = procedural(2, seed=7)
    irls = _fit_errors(procedural_model, depths, light_from_angles(45), {"irls": FitConfig(solver="irls")})
    step = loop.newton_step
    monkeypatch.setattr(loop, "newton_step", lambda *a, **k: 3.0 * step(*a, **k))
    res = {**irls, **_fit_errors(procedural_model, depths, light_from_angles(45), {"broken": FitConfig()})}
    assert np.mean(res["broken"]["err"]) < np.mean(res["irls"]["err"]) + 0.25, res
    assert min(res["broken"]["iterations"]) > 20, res  # it went on by the alternation


def test_the_pass_after_the_albedo_round_is_flagged_and_only_it(procedural_model):
    """The smooth-albedo round runs once the fit has converged and moves the cones, so the next pass's change
    jumps; that pass, and no other, says so (``albedo_round``: the convergence plots mark it). Without the round
    none does."""
    m = procedural_model
    rng = np.random.default_rng(2)
    n_true = m.synthesize(rng.standard_normal(m.n_modes) * np.sqrt(m.eigenvalues) * 0.8)
    s = light_from_angles(40)
    shading = lambertian(n_true, s)
    albedo = 0.8 + 0.2 * np.sin(np.arange(m.n_pixels) / 300.0)  # a smooth albedo for the round to measure
    res = fit(m, shading * albedo, s, FitConfig(albedo_rounds=1))
    flags = [h["albedo_round"] for h in res.history]
    assert flags.count(1.0) == 1 and set(flags) == {0.0, 1.0}
    k = flags.index(1.0)
    assert 0 < k < len(flags) - 1
    assert res.history[k - 1]["change_deg"] < FitConfig().stop_tolerance_deg < res.history[k]["change_deg"]
    none = fit(m, shading * albedo, s, FitConfig(albedo_rounds=0))
    assert all(h["albedo_round"] == 0.0 for h in none.history)
