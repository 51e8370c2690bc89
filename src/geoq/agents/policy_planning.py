"""``planner="policy"`` and ``"policy-net"``: a feedback policy searched through the model.

PILCO's loop (Deisenroth & Rasmussen 2011) on the agent's
:class:`~geoq.models.GPDynamicsModel`: at the start of an episode, once the warm-up is
over and at least :data:`SEARCH_EVERY` transitions have arrived since the last search
(or none was made), the policy is searched again from the current one, scored by the
model's return over ``config.policy_horizon`` steps from the episodes' first states.
``policy``: the model is refitted to the stored transitions first, and the gains of a
:class:`~geoq.models.LinearFeedback` policy are searched by the cross-entropy method
(:func:`~geoq.models.search_gains`). ``policy-net``: the weights of a
:class:`~geoq.models.MLPFeedback` are searched by gradients
(:func:`~geoq.models.search_policy`) through a model of :data:`NET_MODEL`'s settings,
fitted on :class:`~geoq.agents.model_planning.ModelPlanning`'s schedule: up the return of
short roll-outs branched from the newest ``config.window`` stored states
(:data:`BRANCH`), and judged on the whole horizon from the episodes' first states. Training
actions are the policy's plus Gaussian noise of :data:`EXPLORATION` half-ranges
(clipped to the box); greedy actions are the policy's, with no roll-out.

``policy-net`` also tests what a search found on the task itself (``real_test``),
against whatever acted before it, the agent's own ``Q`` included. Each episode's return
is recorded over the search's horizon: as it was where the episode ended in a
termination within the horizon, else rescaled from the steps it ran to the horizon's
(an episode cut short by ``learn``'s budget, or longer than the horizon), but not at
all where it was cut before half the horizon (what it would have returned is then
more guess than measure: a pole alive after one step is not one that balances). A search is
due only once the current actor (``Q`` before the first search) has run
:data:`TEST_EPISODES` episodes. A policy acts only while the model expects it to beat
``Q``: at every search, the model's return for the weights found, less the
``overshoot``, is compared with the mean of ``Q``'s returns (those ``Q`` had when a
policy last replaced it, while a policy acts). The overshoot is how far the returns of
the weights acting at a search fell short of the model's score for them, where they did
by more than :data:`~geoq.models.policy_search.HOLDOUT_SE` standard errors of their mean
(else 0), kept until it is measured again (``Q`` acting: until a policy has acted): a
model that promised more than the task gave is believed that much less (on
``HalfCheetah-v5`` it scored a policy at 2,159 over 1,000 steps, and the task gave
-150). Where it is not above, ``Q`` acts, and the next search starts from the weights
found, unless the model cannot tell (below). Where it is, and the search moved the
weights, they go on trial: they keep acting
only if their episodes' returns are not below the returns of the actor they replaced by
more than :data:`~geoq.models.policy_search.HOLDOUT_SE` standard errors of the
difference of the means; else that actor comes back (the weights before, or ``Q``), and
the next search starts from the weights before with the data the failed ones brought. A
search that keeps the weights it starts from changes no actor.

A model that halts its roll-outs where it has no data pays each halt the least reward
seen for the steps left, so where its roll-outs leave the data within a few steps (a
walker that falls, with the horizon at 1,000), its score is the halts' price and says
nothing of the policy. So until a policy has first replaced ``Q``, weights a search
moved that the model scores below ``Q``'s mean go on trial against ``Q`` all the same
where the model cannot tell: where the same roll-outs (its means, from the newest
:data:`BLIND_STARTS` episodes' first states), each halt paid the most reward seen
instead, would be above ``Q``'s mean (:meth:`FeedbackPlanning._undecided`); an end the
model predicts beyond its data is paid there as a halt, as far as the state is unknown
(a model that has seen a walker only fall predicts a fall wherever it has no data). The
task is asked instead of the model, once a run, while ``Q`` acts: after that trial, won or
lost, ``Q``'s record and the overshoot speak for the model wherever ``Q`` acts (while a
policy acts, the same bound keeps it acting where the task says it is ahead: below).
(Asked at every search where the model could not tell, on ``HalfCheetah-v5``, whose
episodes run 1,000 steps, a trial of two episodes cost 2,000 of a run's 5,000 steps,
and its checkpoints measured a policy the task was about to reject.)

Where a policy acted and the model no longer expects it to beat ``Q``, ``Q`` comes back
on trial against it: ``Q``'s record is as old as the policy's reign, and the task, not
the model, is asked whether ``Q`` now does better. ``Q``'s returns start afresh, and the
next search comes after ``Q``'s :data:`TEST_EPISODES` episodes. There, if the mean of
``Q``'s fresh returns is below the policy's (the means alone: two episodes of a task
that falls or not are too spread for a test to have power), the policy acts again with
the weights the task judged, ``Q``'s fresh returns become its record, and the model's
score cannot send the policy back until the transitions have doubled since
(``q_lost_at``). While ``Q`` acts after a search otherwise, the next waits until the
transitions have doubled (as the model's fits do): a model that expected less than
``Q`` from its best weights is asked again once it has that much more data, not every
:data:`SEARCH_EVERY` transitions.

``Q`` is not sent back where the model cannot tell (the bound above, less the
overshoot) and the task has told: the mean of the acting policy's returns is not below
``Q``'s record. A walker's score is the data's reach there, not the policy's (on
``Walker2d-v5`` it went from 710.0 to -2,381.9 over one refit, 893.6 of its 1,000 steps
halts, while the task gave the same weights 435.4; docs/design-notes.md, part
thirty-four). The policy acts on, and the weights found, if the search moved them, go on
trial against it ``blind``: the model has not scored them, so they are judged as ``Q``
on trial is, on the means. They keep acting only if the mean of their returns is not
below the acting weights'; given the two standard errors, a policy walking at 939.0 and
132.7 gave way to weights that walked at 288.1 (docs/design-notes.md, part thirty-five).

Greedy actions follow a trial as its evidence stands (``greedy_weights``). While ``Q``
is on trial: ``Q``'s, unless the mean of its returns is below the policy's, then the
policy's; its fresh returns so far, and before the first of them, its record from
before the trial. While ``blind`` weights are on trial: the weights they replaced until
the mean of their returns reaches those weights'. A checkpoint taken a few episodes into
a trial, or as it starts, measures the actor the task's returns so far would keep, not
whichever the model's score happened to send back (on ``Walker2d-v5`` a policy greedy
at 638.1 over seven checkpoints, whose training returns stood far above ``Q``'s record,
gave way at the last to ``Q``'s 13.6 as its trial began: docs/design-notes.md, part
thirty-four).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from geoq._typing import FloatArray
from geoq.models import (
    GPDynamicsModel,
    LinearFeedback,
    MLPFeedback,
    ModelSettings,
    PolicyGradientSettings,
    PolicySearchSettings,
    rollout_outcomes,
    search_gains,
    search_policy,
)
from geoq.models.policy_search import HOLDOUT_SE

__all__ = ["BLIND_STARTS", "BRANCH", "EXPLORATION", "NET_MODEL", "SEARCH_EVERY", "SEARCH_WORK",
           "TEST_EPISODES", "FeedbackPlanning"]  # fmt: skip

#: Least number of new transitions between two searches.
SEARCH_EVERY = 100
#: Episodes the current weights run before the next search, with ``real_test``.
TEST_EPISODES = 2
#: Work a ``policy-net`` search's Adam steps may ask of the model per transition stored
#: since the last search (the first: since none), at most the settings' ``budget``, in
#: :attr:`~geoq.models.GPDynamicsModel.step_cost` units: a run's searches together ask
#: at most this much per transition, about 60 ms of one core at 1.5 ns a unit, so
#: 5 minutes for 5,000 transitions, however often searches come and however often they
#: find nothing better (docs/design-notes.md, part fifteen).
SEARCH_WORK = 4e7
#: Episodes whose first states the model's return for a policy is bounded from, where its
#: halts keep it from telling whether the policy beats ``Q`` (module docstring).
BLIND_STARTS = 64
#: Std of the training actions' noise, in half-ranges of the action box.
EXPLORATION = 0.1
#: How a ``policy-net`` search climbs: Adam steps up the return of roll-outs of
#: ``branch_horizon`` model steps from ``particles`` stored states drawn afresh each step
#: (docs/design-notes.md, part fourteen). Both are capped by the search's horizon: the
#: roll-outs' length, and the Adam steps, one per step of it at most, so that a search's
#: work grows with the horizon as the whole-horizon search's did and the searches of a
#: run (one every two episodes or more) cost about the same whatever the episodes' length.
BRANCH = PolicyGradientSettings(branch_horizon=30, particles=64, steps=400)
#: The model a ``policy-net`` search reads: the support in standardised states,
#: calibrated by the newest fifth of the data (a new episode's states lie farther from
#: the old ones than a trajectory's steps from each other), and the rare jumps at a
#: joint's stop left out of the state changes' GPs (docs/design-notes.md, part four).
NET_MODEL = ModelSettings(standardised_support=True, support_holdout=0.2, outlier_mads=6.0)


class FeedbackPlanning:
    """The episodes' start states ``starts`` [N, d_s], the policy (None before the first
    search; ``net``: an :class:`~geoq.models.MLPFeedback`, else a
    :class:`~geoq.models.LinearFeedback`), its weights ``gains`` ([d_a, d_s + 1], or the
    network's ``[n_params]``) and score ``value`` (nan before), and ``searched_at``
    (transitions stored at the last search); with ``real_test`` (module docstring), the
    returns of the episodes run with the current weights ``returns``, the weights they
    replaced, their score and returns and whether they acted ``kept`` (None: none on
    trial), whether the policy acts (``acting``; else ``Q`` does), ``Q``'s returns when
    a policy last replaced it ``q_returns``, the model's last shortfall ``overshoot``,
    the transitions stored when ``Q`` last lost a trial ``q_lost_at`` (0: never), whether
    the weights on trial are there unscored by the model (``blind``, module docstring),
    and the first transition of the running episode ``episode_from`` (-1: none
    recorded)."""

    def __init__(self, obs_dim: int, low: FloatArray, high: FloatArray, horizon: int,
                 net: bool = False, real_test: bool = False):  # fmt: skip
        self.low, self.high, self.net, self.real_test = low, high, net, real_test
        self.returns: list[float] = []
        self.q_returns: list[float] = []
        self.kept: tuple[FloatArray, float, list[float], bool] | None = None
        self.episode_from, self.acting, self.overshoot = -1, False, 0.0
        self.q_lost_at, self.blind = 0, False
        self.settings = PolicySearchSettings(horizon=horizon)
        steps, branch = min(BRANCH.steps, horizon), min(BRANCH.branch_horizon, horizon)
        self.gradient_settings = replace(BRANCH, horizon=horizon, steps=steps,
                                         branch_horizon=branch)  # fmt: skip
        self.starts = np.zeros((0, obs_dim))
        self.policy: LinearFeedback | MLPFeedback | None = None
        self.gains = np.zeros((low.shape[0], obs_dim + 1))
        self.value, self.searched_at = float("nan"), 0

    def due(self, n: int) -> bool:
        """Whether a search is due with ``n`` transitions stored."""
        tested = not self.real_test or len(self.returns) >= TEST_EPISODES
        if self.policy is None:
            return tested
        # Q acts after a search that kept it: ask again once the data have doubled
        on_trial = self.acting or self.kept is not None
        wait = SEARCH_EVERY if on_trial else max(SEARCH_EVERY, self.searched_at)
        return tested and n - self.searched_at >= wait

    @property
    def q_on_trial(self) -> bool:
        """Whether ``Q`` acts on trial against the policy it replaced."""
        return self.kept is not None and self.kept[3] and not self.acting

    @property
    def greedy_weights(self) -> FloatArray | None:
        """The weights greedy actions follow (None: ``Q``'s): the acting policy's, and while
        ``Q`` is on trial, the policy's it replaced where the mean of ``Q``'s returns is
        below that policy's: its fresh returns so far (the verdict, on the episodes run so
        far), or before its first, its record from before the trial. While ``blind``
        weights are on trial, the weights they replaced until the mean of their returns
        (none: not yet) reaches those weights'."""
        if self.acting and self.blind:  # weights on trial the model could not score
            assert self.kept is not None
            gains, _, returns, _ = self.kept
            if not self.returns or np.mean(self.returns) < np.mean(returns):
                return gains
        if self.acting:
            return self.gains
        if self.q_on_trial:
            assert self.kept is not None
            gains, _, returns, _ = self.kept
            q_returns = self.returns or self.q_returns
            if returns and q_returns and np.mean(q_returns) < np.mean(returns):
                return gains
        return None

    @property
    def horizon(self) -> int:
        """Model steps a search scores its policies over."""
        return self.gradient_settings.horizon if self.net else self.settings.horizon

    def close_episode(self, rewards: FloatArray, terminated: np.ndarray) -> None:
        """The episode before the stored transitions' rewards ``rewards`` [n] and
        termination flags ``terminated`` [n] ends: if it was recorded, its return over
        the horizon (module docstring) joins ``returns``."""
        steps = len(rewards) - self.episode_from if self.episode_from >= 0 else 0
        ended = steps > 0 and bool(terminated[-1]) and steps <= self.horizon
        if steps > 0 and (ended or 2 * steps >= self.horizon):
            ret = float(rewards[self.episode_from :].sum())
            self.returns.append(ret if ended else ret * self.horizon / steps)
        self.episode_from = -1

    def open_episode(self, n: int) -> None:
        """An episode starts after ``n`` stored transitions: recorded with ``real_test``
        (whoever acts), else if the policy acts."""
        self.episode_from = n if self.real_test or self.acting else -1

    def _calibrate(self) -> None:
        """How far the acting weights' returns fell short of the model's score for them
        (``overshoot``, module docstring): measured where a policy acts with two returns or
        more, 0 where they are not below it by :data:`~geoq.models.policy_search.HOLDOUT_SE`
        standard errors of their mean."""
        if not self.acting or len(self.returns) < 2:
            return
        returns = np.array(self.returns)
        short = self.value - returns.mean()
        se = returns.std(ddof=1) / np.sqrt(len(returns))
        self.overshoot = float(short) if short > HOLDOUT_SE * se else 0.0

    def _judge(self) -> bool:
        """Keep the actor on trial, or bring back the one it replaced (module docstring);
        whether ``Q``, on trial, lost to the policy it replaced."""
        if self.kept is None:
            return False
        # Q sent back by the model's level, or weights the model could not score: the means
        q_trial, blind = self.q_on_trial, self.blind
        gains, value, returns, acting = self.kept
        self.kept, self.blind = None, False
        new, old = np.array(self.returns), np.array(returns)
        if len(new) >= 2 and len(old) >= 2:
            se = np.sqrt(new.var(ddof=1) / len(new) + old.var(ddof=1) / len(old))
            se = 0.0 if q_trial or blind else se
            if new.mean() < old.mean() - HOLDOUT_SE * se:
                if q_trial:  # Q's returns, fresh, are what the policy is set against
                    self.q_returns = list(self.returns)
                self.gains, self.value, self.returns, self.acting = gains, value, returns, acting
                return q_trial
        return False

    def _undecided(self, model: GPDynamicsModel, q_mean: float) -> bool:
        """Whether the model's return for the weights found would be above ``q_mean`` were
        each halt paid the most reward seen rather than the least, less the overshoot: its
        means rolled out from the newest :data:`BLIND_STARTS` episodes' first states, an
        end predicted beyond the data no more believed than the state there (paid as a
        halt as far as the state is unknown)."""
        assert self.policy is not None
        policy, gains = self.policy, self.gains
        returns, halted = rollout_outcomes(model, self.starts[-BLIND_STARTS:],
                                           lambda t, S, rows: policy.act(gains, S),
                                           self.horizon, gamma=1.0, noise=None,
                                           trust_ends=False)  # fmt: skip
        spread = float(model.reward_range[1] - model.reward_range[0])
        return float(np.mean(returns + halted * spread)) - self.overshoot > q_mean

    def _make(self, center: FloatArray, scale: FloatArray) -> LinearFeedback | MLPFeedback:
        kind = MLPFeedback if self.net else LinearFeedback
        return kind(self.low, self.high, center, scale)

    def search(self, model: GPDynamicsModel, n: int, rng: np.random.Generator,
               states: FloatArray | None = None) -> None:  # fmt: skip
        """Search the gains through ``model`` (fitted on ``n`` transitions), from the current;
        ``states`` [N, d_s]: the stored states a ``policy-net`` search branches from."""
        if self.policy is None:  # the standardisation is fixed at the first search
            d = model.obs_dim
            self.policy = self._make(model.x_mean[:d], model.x_scale[:d])
            if isinstance(self.policy, MLPFeedback):
                self.gains = self.policy.initial(rng)
        elif self.real_test:
            self._calibrate()
            if self._judge():
                self.q_lost_at = n
        before = (self.gains, self.value, self.returns, self.acting)
        if isinstance(self.policy, MLPFeedback):
            c = self.gradient_settings
            c = replace(c, budget=min(c.budget, SEARCH_WORK * (n - self.searched_at)))
            self.gains, self.value = search_policy(model, self.policy, self.gains, self.starts,
                                                   rng, c, states)  # fmt: skip
        else:
            self.gains, self.value = search_gains(model, self.policy, self.gains, self.starts,
                                                  rng, self.settings)  # fmt: skip
        self.searched_at = n
        q_returns = self.q_returns if before[3] else before[2]
        q_mean = float(np.mean(q_returns)) if q_returns else float("nan")
        expected = not q_returns or self.value - self.overshoot > q_mean
        moved = not np.array_equal(self.gains, before[0])
        untried = self.real_test and not before[3] and not self.q_returns
        mine = before[2] if before[3] else []  # the acting policy's returns
        ahead = self.real_test and bool(mine) and bool(np.mean(mine) >= q_mean)
        blind = False
        if not expected and ((moved and untried) or ahead) and self._undecided(model, q_mean):
            expected, blind = True, ahead  # the model cannot tell: the task is asked (Q's: once)
        if not self.real_test:
            self.acting = True
        elif not expected and before[3] and n < 2 * self.q_lost_at:
            self.gains, self.value = before[0], before[1]  # the task answered lately: they act
        elif not expected and before[3]:  # Q again, on trial against the policy
            self.kept, self.returns, self.acting = before, [], False
        elif expected and moved:
            if not before[3]:
                self.q_returns = list(before[2])
            self.kept, self.returns, self.acting, self.blind = before, [], True, blind

    def action(self, s: FloatArray, rng: np.random.Generator | None) -> FloatArray:
        """The policy's action ``[1, d_a]`` at ``s`` [1, d_s]: with ``rng`` the acting
        weights' plus the noise, else the :attr:`greedy_weights`'."""
        assert self.policy is not None
        if rng is None:
            weights = self.greedy_weights
            assert weights is not None
            return self.policy.act(weights, s)
        assert self.acting
        a = self.policy.act(self.gains, s)
        noise = EXPLORATION * self.policy.half * rng.standard_normal(a.shape)
        return np.clip(a + noise, self.low, self.high)

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> dict[str, Any]:
        """The starts, the real returns (``Q``'s too), the overshoot and the running
        episode's start, and once searched the policy, its gains and their score, whether
        it acts, and the actor on trial replaced."""
        arrays: dict[str, Any] = {
            "policy_starts": self.starts,
            "policy_returns": np.array(self.returns, dtype=np.float64),
            "policy_q_returns": np.array(self.q_returns, dtype=np.float64),
            "policy_episode_from": np.array(self.episode_from),
            "policy_overshoot": np.array(self.overshoot),
            "policy_q_lost_at": np.array(self.q_lost_at),
            "policy_blind": np.array(self.blind),
        }
        if self.policy is not None:
            arrays |= {
                "policy_center": self.policy.center, "policy_scale": self.policy.scale,
                "policy_gains": self.gains, "policy_value": np.array(self.value),
                "policy_searched_at": np.array(self.searched_at),
                "policy_acting": np.array(self.acting),
            }  # fmt: skip
        if self.kept is not None:
            gains, value, returns, acting = self.kept
            arrays |= {"policy_kept_gains": gains, "policy_kept_value": np.array(value),
                       "policy_kept_returns": np.array(returns, dtype=np.float64),
                       "policy_kept_acting": np.array(acting)}  # fmt: skip
        return arrays

    def restore(self, a: dict[str, Any]) -> None:
        """Inverse of :meth:`to_arrays` (``ValueError`` where it does not fit)."""
        starts = np.asarray(a.get("policy_starts", self.starts), dtype=np.float64)
        if starts.ndim != 2 or starts.shape[1] != self.starts.shape[1]:
            raise ValueError(f"policy_starts must be [N, {self.starts.shape[1]}]")
        if not np.all(np.isfinite(starts)):
            raise ValueError("policy_starts must be finite")
        self.starts = starts
        self.returns = list(_finite(a.get("policy_returns", []), "policy_returns", None))
        self.q_returns = list(_finite(a.get("policy_q_returns", []), "policy_q_returns", None))
        self.episode_from = int(a.get("policy_episode_from", -1))
        overshoot = _finite([a.get("policy_overshoot", 0.0)], "policy_overshoot", (1,))
        if overshoot[0] < 0.0:
            raise ValueError(f"policy_overshoot must be >= 0, got {overshoot[0]}")
        self.overshoot = float(overshoot[0])
        q_lost_at = np.asarray(a.get("policy_q_lost_at", 0))
        if q_lost_at.shape != () or q_lost_at.dtype.kind not in "iu" or q_lost_at < 0:
            raise ValueError(f"policy_q_lost_at must be one integer >= 0, got {q_lost_at!r}")
        self.q_lost_at = int(q_lost_at)
        self.blind = _flag(a.get("policy_blind", False), "policy_blind")
        if "policy_gains" not in a:
            return
        policy = self._make(a["policy_center"], a["policy_scale"])
        shape = (policy.n_params,) if isinstance(policy, MLPFeedback) else policy.shape
        self.policy, self.gains = policy, _finite(a["policy_gains"], "policy_gains", shape)
        self.value, self.searched_at = float(a["policy_value"]), int(a["policy_searched_at"])
        self.acting = _flag(a.get("policy_acting", True), "policy_acting")
        if "policy_kept_gains" in a:
            kept = _finite(a["policy_kept_gains"], "policy_kept_gains", shape)
            returns = _finite(a["policy_kept_returns"], "policy_kept_returns", None)
            acting = _flag(a.get("policy_kept_acting", True), "policy_kept_acting")
            self.kept = (kept, float(a["policy_kept_value"]), list(returns), acting)
        if self.blind and (self.kept is None or not self.acting or not self.kept[3]):
            raise ValueError(
                "policy_blind must be False unless a policy's weights act on trial "
                "against another policy's"
            )


def _finite(value: Any, name: str, shape: tuple[int, ...] | None) -> FloatArray:
    """``value`` as finite float64 of ``shape`` (None: any 1-D), else ``ValueError``."""
    array = np.asarray(value, dtype=np.float64)
    if (array.ndim != 1 if shape is None else array.shape != shape) or not np.all(
        np.isfinite(array)
    ):
        raise ValueError(f"{name} must be finite of shape {shape or '[N]'}, got {array.shape}")
    return array


def _flag(value: Any, name: str) -> bool:
    """``value`` as a bool, from a 0-d boolean array or a bool, else ``ValueError``."""
    array = np.asarray(value)
    if array.shape != () or array.dtype != np.bool_:
        raise ValueError(f"{name} must be one boolean, got {array.dtype}, shape {array.shape}")
    return bool(array)
