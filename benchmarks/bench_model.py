"""The dynamics model's prediction, against each output's GP asked in turn.

A planner asks the model about ``P`` particles at every model step of every plan:
``GPDynamicsModel.predict_mean`` (one compiled loop over every output's basis) and,
with the std, ``GPDynamicsModel.predict``; a sampled roll-out's step,
``GPDynamicsModel.draw``, asks only the state changes for their std. The baseline, in
the same process, asks each output's :class:`~geoq.gp.SparseOnlineGP` in turn, without
and with the std (every output's, for ``draw`` too). Sizes:
InvertedPendulum's (4 states, 1 action: 6 outputs) and Reacher's (10 + 2: 12), on
2,000 transitions of smooth random dynamics, 200 basis vectors per output, 64
particles (the planner's default samples).
"""

from __future__ import annotations

import time

import numpy as np

from geoq.models import GPDynamicsModel, ModelSettings


def _model(d_s: int, d_a: int, n: int, max_bv: int) -> GPDynamicsModel:
    rng = np.random.default_rng(0)
    S, A = rng.normal(size=(n, d_s)), rng.uniform(-1.0, 1.0, size=(n, d_a))
    S2 = S + 0.1 * np.sin(S @ rng.normal(size=(d_s, d_s))) + 0.1 * A @ rng.normal(size=(d_a, d_s))
    R, T = -np.sum(S**2, axis=1), (np.abs(S[:, 0]) > 2.0).astype(float)
    return GPDynamicsModel(d_s, d_a, ModelSettings(max_bv=max_bv)).fit(S, A, R, S2, T, rng)


def _seconds(fn, repeats: int) -> float:  # type: ignore[no-untyped-def]
    fn()
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - start) / repeats


def main(quick: bool = False) -> None:
    n, max_bv, particles, repeats = (200, 30, 16, 3) if quick else (2000, 200, 64, 50)
    print(f"{'task sizes':<22} {'what':<11} {'model':>9} {'per output':>11} {'ratio':>7}")
    for name, d_s, d_a in (("4 states + 1 action", 4, 1), ("10 states + 2 actions", 10, 2)):
        model = _model(d_s, d_a, n, max_bv)
        rng = np.random.default_rng(1)
        S, A = rng.normal(size=(particles, d_s)), rng.uniform(-1, 1, size=(particles, d_a))
        X = (np.hstack([S, A]) - model.x_mean) / model.x_scale
        calls = {
            "means": lambda: model.predict_mean(S, A),  # noqa: B023
            "means, std": lambda: model.predict(S, A),  # noqa: B023
            "draw": lambda: model.draw(S, A, rng),  # noqa: B023
        }
        for what, call in calls.items():
            std = what != "means"
            ours = _seconds(call, repeats)
            each = _seconds(
                lambda: [gp.predict(X, return_std=std) for gp in model.gps if gp is not None],  # noqa: B023
                repeats,
            )
            print(f"{name:<22} {what:<11} {1e3 * ours:>7.2f}ms {1e3 * each:>9.2f}ms "
                  f"{each / ours:>6.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
