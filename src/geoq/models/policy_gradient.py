"""A neural feedback policy searched through a model by its return's gradient.

:class:`~geoq.models.LinearFeedback` cannot reach a target it must first turn its
joints towards (``Reacher-v5``: the best linear policy, searched on the task itself,
scores -8.3; docs/design-notes.md). :class:`MLPFeedback` is one hidden layer of
``tanh`` units, ``a = mid + half * tanh(W2 tanh(W1 z + b1) + b2)`` with ``z`` the
standardised state: hundreds of weights, too many for the cross-entropy method, so
they are searched as PILCO searches its policies, by the gradient of the model's
predicted return (Deisenroth & Rasmussen 2011), here along roll-outs from sampled
starts (pathwise gradients with the draws held fixed: PEGASUS, Ng & Jordan 2000; as in
Deep PILCO, Gal et al. 2016). By default the roll-outs follow the model's means
(``sampled``: draws from its predictive Gaussians, whose stds are then held constant in
the gradient: the means carry it); measured on ``Reacher-v5`` the means did as well,
at a fifth of the cost.

:func:`soft_return` differentiates, by hand and in reverse through the ``T`` steps,
the return of roll-outs that go on after the model ends or halts them, weighted by the
chance they have not: a step's termination output ``p`` (clipped to ``[0, 1]``) and its
halt ``u = min(max(distance - 1, 0), 1)`` where the model has no data
(:mod:`geoq.models.planner`) make the weight ``w_{t+1} = w_t (1 - p_t)(1 - u_t)``, and
a halt is paid the least reward seen for the steps left, as there.
:func:`search_policy` takes Adam steps (Kingma & Ba 2015) up this smooth return, then
keeps the result only if it also beats the current policy on the exact returns of
fresh starts (:func:`~geoq.models.rollout_returns`, whose ends are the termination
output above 1/2), by :data:`~geoq.models.policy_search.HOLDOUT_SE` standard errors of
the paired differences. The steps stop where the gradient (or its square) overflows:
through long roll-outs of a model whose steps stretch the states, the return can be
chaotic in the weights, its gradient astronomically large and no guide.

Where it is, even a finite gradient can be: on a cart-pole swing-up, whose pole the
searched policy spun through the top, the smooth return over the episode fell after
one Adam step at every step size tried (docs/design-notes.md, part thirteen). With
``branch_horizon`` the Adam steps climb the return of short roll-outs branched from
stored states instead (``branch_from``; MBPO's branched roll-outs, Janner et al. 2019;
the receding horizon a model-predictive controller plans over, learned once into the
policy), fresh states at every step: a short horizon keeps the gradient a guide, and
states from everywhere the task has been teach the policy what to do there (near the
top: hold the pole up) where the episode's first states teach only how to start. The
found weights are still judged on the whole horizon from the episodes' starts. With
``whole_steps`` a second climb runs beside it, up the whole horizon's return from the
starts, and the holdout keeps the better of the two found weights (the agent's search
does not: tried and measured in docs/design-notes.md, part fifteen).

A branched roll-out's return counts only its ``branch_horizon`` steps, where the judge's
roll-outs run on: on a task that pays for being alive, ending costs a short branch a few
steps' pay and the judge the rest of the horizon's. With ``close_branch`` the branched
roll-outs are closed as the judge's would go on, for ``horizon - branch_horizon`` steps
more: the data's mean reward for each where a roll-out still runs, nothing where it ended,
and the least reward for each where it halted. This is model-based value expansion's
closing value (MVE, Feinberg et al. 2018) at its crudest, one constant per step: it tells
a roll-out alive from one ended or lost, and nothing more. With ``close_halts`` False only
ending loses it: a roll-out's closing value is weighted by the product of its steps'
``1 - p`` alone, so that falling costs a branch what it costs the judge and leaving the
data what it costs with no closing value.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from geoq._typing import FloatArray
from geoq._validation import as_float_matrix, as_float_vector, check_int, check_real
from geoq.models.dynamics import GPDynamicsModel
from geoq.models.planner import rollout_returns
from geoq.models.policy_search import HOLDOUT_SE, FeedbackBase

__all__ = ["MLPFeedback", "PolicyGradientSettings", "search_policy", "soft_return"]


@dataclass(frozen=True)
class PolicyGradientSettings:
    """The gradient search's settings (weights in the standardised state's units)."""

    horizon: int = 300
    """Model steps of each roll-out (capped at the task's time limit by the caller)."""
    particles: int = 16
    """Sampled roll-outs the return is averaged over."""
    steps: int = 100
    """Adam steps per search."""
    learning_rate: float = 0.01
    """Adam's step size."""
    sampled: bool = False
    """Draw the state changes from the model's predictive Gaussians in the roll-outs
    (False: follow their means; the particles differ by their starts)."""
    holdout_particles: int = 64
    """Roll-outs from fresh starts that the found weights must win on."""
    branch_horizon: int = 0
    """Model steps of the roll-outs the Adam steps climb when they branch from stored
    states (``branch_from`` given to :func:`search_policy`): ``particles`` states drawn
    afresh at each step, the iterate after the last step found (0: the roll-outs run the
    whole ``horizon`` from the episodes' starts, and the best iterate is found). The
    found weights are judged on the whole ``horizon`` from the starts either way."""
    whole_steps: int = 0
    """With ``branch_from``: Adam steps of a second climb beside the branched one, up the
    return of ``whole_particles`` roll-outs over the whole ``horizon`` from the starts (its
    best iterate found, as with no branch). The holdout then keeps whichever of the two
    found weights returns more on its fresh starts, if that one beats the current weights
    (0: the branched climb alone)."""
    whole_particles: int = 16
    """Roll-outs the second climb's return is averaged over."""
    close_branch: bool = False
    """With ``branch_from``: close each branched roll-out with a value for the rest of the
    whole ``horizon``, ``horizon - branch_horizon`` steps more, as the judge's roll-outs
    run them: the data's mean reward for each of those steps where the roll-out still runs
    (none where it ended), and a halt paid the least reward for them too (module
    docstring). False: a branched roll-out is worth its ``branch_horizon`` steps alone."""
    close_halts: bool = True
    """With ``close_branch``: a halted roll-out loses the closing value, as an ended one does,
    and its halt is paid the least reward for the closing steps too (True). False: only
    ending loses it; each roll-out's closing value is weighted by the chance it has not
    ended (the termination outputs' ``1 - p`` alone), and a halt is paid the least reward for
    the branch's steps left and no more, as with no closing value (module docstring)."""
    budget: float = 4e10
    """Work the Adam steps of each climb may ask of the model per search, in
    :attr:`~geoq.models.GPDynamicsModel.step_cost` units summed over the particles' steps
    (ended roll-outs cost nothing); the steps stop once it is spent. About a minute of one
    core at 1.5 ns a unit (docs/design-notes.md, part twelve)."""

    def __post_init__(self) -> None:
        check_int(self.horizon, "horizon", minimum=1, maximum=100_000)
        check_int(self.particles, "particles", minimum=1, maximum=100_000)
        check_int(self.holdout_particles, "holdout_particles", minimum=2, maximum=100_000)
        check_int(self.steps, "steps", minimum=0, maximum=100_000)
        check_int(self.whole_steps, "whole_steps", minimum=0, maximum=100_000)
        check_int(self.whole_particles, "whole_particles", minimum=1, maximum=100_000)
        check_int(self.branch_horizon, "branch_horizon", minimum=0, maximum=self.horizon)
        check_real(self.learning_rate, "learning_rate", low=0.0, high=10.0)
        check_real(self.budget, "budget", low=0.0)


class MLPFeedback(FeedbackBase):
    """``a = mid + half * tanh(W2 tanh(W1 z + b1) + b2)``, ``z = (s - center) / scale``,
    with ``hidden`` units; the weights are one flat vector ``[n_params]``
    (``W1`` [H, d_s], ``b1`` [H], ``W2`` [d_a, H], ``b2`` [d_a])."""

    def __init__(
        self, low: FloatArray, high: FloatArray, center: FloatArray, scale: FloatArray,
        hidden: int = 32,
    ) -> None:  # fmt: skip
        super().__init__(low, high, center, scale)
        self.hidden = check_int(hidden, "hidden", minimum=1, maximum=10_000)
        d, H, k = self.center.shape[0], self.hidden, self.mid.shape[0]
        self._sizes = [(H, d), (H,), (k, H), (k,)]
        self._ends = np.cumsum([H * d, H, k * H, k]).tolist()
        self.n_params = self._ends[-1]

    def initial(self, rng: np.random.Generator) -> FloatArray:
        """Random first weights ``[n_params]``: hidden units of unit-variance inputs, and
        zero output weights (the box's centre everywhere)."""
        d, H = self.center.shape[0], self.hidden
        W1 = rng.standard_normal((H, d)) / np.sqrt(d)
        b1 = rng.standard_normal(H)
        return np.concatenate([W1.ravel(), b1, np.zeros(self.n_params - H * d - H)])

    def unpack(self, params: FloatArray) -> list[FloatArray]:
        """``[W1, b1, W2, b2]`` (views) of the flat weights."""
        if params.shape != (self.n_params,):
            raise ValueError(f"params must have shape ({self.n_params},), got {params.shape}")
        bounds = zip([0, *self._ends[:-1]], self._ends, self._sizes, strict=True)
        return [params[a:b].reshape(shape) for a, b, shape in bounds]

    def act(self, params: FloatArray, S: FloatArray) -> FloatArray:
        """Actions ``[P, d_a]`` at states ``[P, d_s]``."""
        return self.forward(params, S)[0]

    def forward(self, params: FloatArray, S: FloatArray) -> tuple[FloatArray, tuple]:
        """Actions ``[P, d_a]`` and what :meth:`backward` needs."""
        W1, b1, W2, b2 = self.unpack(params)
        z = (S - self.center) / self.scale
        h = np.tanh(z @ W1.T + b1)
        y = np.tanh(h @ W2.T + b2)
        return self.mid + self.half * y, (z, h, y)

    def backward(
        self, params: FloatArray, cache: tuple, grad_actions: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The gradients ``[n_params]`` (summed over the batch) and ``[P, d_s]`` of
        ``sum(grad_actions * actions)`` with respect to the weights and the states."""
        W1, _, W2, _ = self.unpack(params)
        z, h, y = cache
        gy = grad_actions * self.half * (1.0 - y**2)  # [P, d_a]
        gh = (gy @ W2) * (1.0 - h**2)  # [P, H]
        grad = np.concatenate(
            [(gh.T @ z).ravel(), gh.sum(axis=0), (gy.T @ h).ravel(), gy.sum(axis=0)]
        )
        return grad, (gh @ W1) / self.scale


def soft_return(
    model: GPDynamicsModel,
    policy: MLPFeedback,
    params: FloatArray,
    starts: FloatArray,
    normals: FloatArray,
    tail: int = 0,
    tail_reward: float = 0.0,
    close_halts: bool = True,
) -> tuple[float, FloatArray]:
    """The mean smooth return (module docstring) of ``P`` roll-outs from ``starts`` [P, d_s]
    under the weights ``params`` over ``T`` model steps with the state changes' standard
    normals ``normals`` [T, P, d_s], and its gradient ``[n_params]``. ``tail`` steps more
    close the roll-outs (0: no closing value): ``tail_reward`` for each, times the roll-out's
    weight after the ``T`` steps, and a halt paid the least reward for them too; or, with
    ``close_halts`` False, times the product of its steps' ``1 - p`` alone (the chance it
    has not ended; a halt then keeps it, and is paid the least reward for the ``T`` steps'
    rest alone)."""
    tail = check_int(tail, "tail", minimum=0)
    tail_reward = check_real(tail_reward, "tail_reward")
    value, grad, _ = _soft_return(model, policy, params, starts, normals, tail, tail_reward,
                                  bool(close_halts))  # fmt: skip
    return value, grad


def _soft_return(
    model: GPDynamicsModel,
    policy: MLPFeedback,
    params: FloatArray,
    starts: FloatArray,
    normals: FloatArray,
    tail: int = 0,
    tail_reward: float = 0.0,
    close_halts: bool = True,
) -> tuple[float, FloatArray, int]:
    """:func:`soft_return`, and the particles' model steps it took."""
    T, (P, d) = normals.shape[0], starts.shape
    r_least = float(model.reward_range[0])
    halt_tail, closing = (tail if close_halts else 0), tail * tail_reward
    S, w, total = starts.copy(), np.ones(P), np.zeros(P)
    alive = np.ones(P)  # the product of 1 - p alone: what carries the closing for ends
    rows, tape = np.arange(P), []
    for t in range(T):
        rows = rows[w[rows] > 0.0]  # an ended or halted roll-out adds nothing more
        if rows.size == 0:
            break
        s, w_t = S[rows], w[rows]
        A, cache = policy.forward(params, s)
        mean, jac = model.mean_gradients(s, A)
        if normals[t].any():  # the same means, plus the stds times the normals
            s = model.draw(s, A, normals[t][rows])[1]
        else:  # zero normals: the means' roll-outs, no std asked for
            s = s + mean[:, :d]
        S[rows] = s
        end = np.clip(mean[:, d + 1], 0.0, 1.0)
        dist, dist_grad = model.support.distance_gradient(s)
        halt = np.clip(dist - 1.0, 0.0, 1.0)
        rest = (T - 1 - t + halt_tail) * r_least
        reward = mean[:, d] + (1.0 - end) * halt * rest
        total[rows] += w_t * reward
        live = ((mean[:, d + 1] > 0) & (mean[:, d + 1] < 1), (dist > 1) & (dist < 2))
        tape.append((rows, cache, jac, w_t, alive[rows], reward, end, halt, rest, dist_grad,
                     *live))  # fmt: skip
        w[rows] = w_t * (1.0 - end) * (1.0 - halt)
        alive[rows] *= 1.0 - end
    if tail:  # the closing value of the roll-outs still running (not ended)
        total += (w if close_halts else alive) * closing
    grad = np.zeros(policy.n_params)
    g_next = np.zeros((P, d))
    gw_next = np.full(P, closing if close_halts else 0.0)  # what carries the closing value
    ga_next = np.full(P, 0.0 if close_halts else closing)
    for rows, cache, jac, w, a, reward, end, halt, rest, dist_grad, end_live, halt_live in reversed(
        tape
    ):
        gw, ga = gw_next[rows], ga_next[rows]
        g_end = -w * halt * rest - gw * w * (1.0 - halt) - ga * a
        g_halt = w * (1.0 - end) * rest - gw * w * (1.0 - end)
        g_state = g_next[rows] + (g_halt * halt_live)[:, None] * dist_grad
        g_mean = np.zeros(jac.shape[:2])
        g_mean[:, :d], g_mean[:, d], g_mean[:, d + 1] = g_state, w, g_end * end_live
        g_input = np.einsum("pj,pjk->pk", g_mean, jac)
        g_params, g_policy_state = policy.backward(params, cache, g_input[:, d:])
        grad += g_params
        g_next[rows] = g_state + g_input[:, :d] + g_policy_state
        gw_next[rows] = reward + gw * (1.0 - end) * (1.0 - halt)
        ga_next[rows] = ga * (1.0 - end)
    return float(total.mean()), grad / P, sum(len(step[0]) for step in tape)


def search_policy(
    model: GPDynamicsModel,
    policy: MLPFeedback,
    params: FloatArray,
    starts: FloatArray,
    rng: np.random.Generator,
    settings: PolicyGradientSettings | None = None,
    branch_from: FloatArray | None = None,
) -> tuple[FloatArray, float]:
    """Weights ``[n_params]`` found by Adam up :func:`soft_return` from ``params``, on
    ``particles`` starts drawn from ``starts`` [N, d_s] and normals drawn once, and their
    exact return on fresh draws; the current ``params`` and theirs unless the found weights
    beat them there by :data:`~geoq.models.policy_search.HOLDOUT_SE` paired standard
    errors (module docstring). The Adam steps stop after ``steps``, or once they have
    asked the model for ``budget`` units of work (the particles' model steps times
    :attr:`~geoq.models.GPDynamicsModel.step_cost`). ``branch_from`` [M, d_s], with a
    ``branch_horizon``: the stored states the Adam steps' roll-outs start from instead,
    ``particles`` of them drawn at each step (module docstring); with ``whole_steps`` too,
    a second climb over the whole horizon from the starts, and the holdout's better of the
    two found weights is the one set against ``params``."""
    c = settings or PolicyGradientSettings()
    params = as_float_vector(params, "params", policy.n_params)
    starts = as_float_matrix(starts, "starts", model.obs_dim)
    branch = None
    if c.branch_horizon > 0 and branch_from is not None:
        branch = as_float_matrix(branch_from, "branch_from", model.obs_dim)
        if len(branch) == 0:
            raise ValueError("branch_from must hold at least one state")
    found = [_climb(model, policy, params, starts, rng, c, branch)]
    if branch is not None and c.whole_steps > 0:
        whole = replace(c, steps=c.whole_steps, particles=c.whole_particles)
        found.append(_climb(model, policy, params, starts, rng, whole, None))
    picked = starts[rng.integers(len(starts), size=c.holdout_particles)]
    fresh = rng.standard_normal((c.horizon, *picked.shape)) if c.sampled else None

    def returns(weights: FloatArray) -> FloatArray:
        return rollout_returns(model, picked, lambda t, S, rows: policy.act(weights, S),
                               c.horizon, gamma=1.0, noise=fresh)  # fmt: skip

    old = returns(params)
    new = [returns(weights) for weights in found]
    best = int(np.argmax([r.mean() for r in new]))
    gain = new[best] - old
    se = gain.std(ddof=1) / np.sqrt(len(gain))
    if gain.mean() > HOLDOUT_SE * se:
        return found[best], float(new[best].mean())
    return params, float(old.mean())


def _climb(
    model: GPDynamicsModel,
    policy: MLPFeedback,
    params: FloatArray,
    starts: FloatArray,
    rng: np.random.Generator,
    c: PolicyGradientSettings,
    branch: FloatArray | None,
) -> FloatArray:
    """The weights one climb of :func:`search_policy` finds from ``params``: ``c.steps``
    Adam steps up :func:`soft_return` over the whole ``c.horizon`` from ``starts`` (the best
    iterate), or, ``branch`` [M, d_s] given, over ``c.branch_horizon`` from its states (the
    last iterate), closed by the data's mean reward with ``c.close_branch``."""
    horizon = c.horizon if branch is None else c.branch_horizon
    closed = branch is not None and c.close_branch
    tail = c.horizon - c.branch_horizon if closed else 0
    tail_reward = float(model.y_mean[model.obs_dim]) if closed else 0.0
    picked = starts[rng.integers(len(starts), size=c.particles)]
    normals = rng.standard_normal((horizon, c.particles, model.obs_dim)) * c.sampled
    theta, m, v = params.copy(), np.zeros_like(params), np.zeros_like(params)
    best, best_value = params, -np.inf
    beta1, beta2 = 0.9, 0.999
    unit, spent = model.step_cost, 0.0
    for k in range(1, c.steps + 1):
        if branch is not None:
            picked = branch[rng.integers(len(branch), size=c.particles)]
        value, grad, taken = _soft_return(model, policy, theta, picked, normals, tail,
                                          tail_reward, c.close_halts)  # fmt: skip
        with np.errstate(over="ignore"):  # a return chaotic in the weights: stop there
            square = grad * grad
        if not (np.isfinite(value) and np.all(np.isfinite(square))):
            break
        if value > best_value and branch is None:
            best, best_value = theta.copy(), value
        spent += taken * unit
        if spent >= c.budget:  # a step after this one would not be scored
            break
        m = beta1 * m + (1 - beta1) * grad
        v = beta2 * v + (1 - beta2) * square
        step = (m / (1 - beta1**k)) / (np.sqrt(v / (1 - beta2**k)) + 1e-8)
        theta = theta + c.learning_rate * step
        if branch is not None:
            best = theta
    return best
