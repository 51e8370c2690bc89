"""``planner="policy-net"``'s test on the task itself (:mod:`geoq.agents.policy_planning`):
weights a search put in place run :data:`TEST_EPISODES` episodes, and give way to the
actor before them (weights, or the agent's ``Q``) if their returns are worse by more
than two standard errors; a policy acts only while the model expects it to beat ``Q``,
and where it no longer does, ``Q`` acts on trial against it, judged on the means, unless
the model cannot tell and the task puts the policy ahead: then the weights found go on
trial unscored, judged on the means too."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from geoq._typing import FloatArray
from geoq.agents import policy_planning
from geoq.agents.policy_planning import (
    BRANCH,
    SEARCH_EVERY,
    SEARCH_WORK,
    TEST_EPISODES,
    FeedbackPlanning,
)
from geoq.models import GPDynamicsModel, PolicyGradientSettings, rollout_outcomes

LOW, HIGH = np.array([-1.0]), np.array([1.0])


def _planning() -> tuple[FeedbackPlanning, GPDynamicsModel, np.random.Generator]:
    """A policy on a model of a double integrator paid ``-x^2``, searched with no Adam
    step (the search keeps the weights it starts from)."""
    rng = np.random.default_rng(0)
    S, A = rng.uniform(-1, 1, (200, 2)), rng.uniform(-1, 1, (200, 1))
    change = np.column_stack([0.1 * S[:, 1], 0.1 * A[:, 0]])
    model = GPDynamicsModel(2, 1).fit(S, A, -(S[:, 0] ** 2), S + change, np.zeros(200), rng)
    planning = FeedbackPlanning(2, LOW, HIGH, horizon=10, net=True, real_test=True)
    planning.gradient_settings = PolicyGradientSettings(horizon=10, steps=0)
    planning.starts = rng.uniform(-0.5, 0.5, (8, 2))
    planning.returns = [0.0] * TEST_EPISODES  # Q's episodes: no cost, beyond any policy
    planning.search(model, 0, rng)
    # the model does not expect the weights to beat Q: Q keeps acting, and no trial
    assert planning.policy is not None and planning.kept is None and not planning.acting
    assert planning.q_returns == [] and planning.value < 0.0
    # from here a policy acts, and Q's returns were far below what the model expects of it
    planning.acting, planning.q_returns = True, [-50.0] * TEST_EPISODES
    return planning, model, rng


def test_an_episode_adds_its_return_over_the_horizon_whoever_acts() -> None:
    """Oracle: the sums by hand; an episode that did not end in a termination within the
    horizon (10 steps) is rescaled from its steps to the horizon's, and not recorded if
    it was cut before half of it."""
    planning, _, _ = _planning()
    rewards = np.array([1.0, 2.0, 3.0, -1.0, 0.5] + [1.0] * 10)
    ended = np.zeros(len(rewards), dtype=bool)
    planning.returns = []
    planning.open_episode(1)
    planning.close_episode(rewards[:3], ended[:3])  # cut after 2 steps: not recorded
    planning.open_episode(3)
    planning.close_episode(rewards[:5], ended[:5] | (np.arange(5) == 4))  # a termination
    planning.close_episode(rewards[:5], ended[:5])  # closed already: nothing more
    planning.open_episode(3)
    planning.close_episode(rewards, ended | True)  # a termination, after 12 steps
    planning.open_episode(0)
    planning.close_episode(rewards[:5], ended[:5])  # cut after 5 steps: 5.5 * 10 / 5
    assert planning.returns == [-0.5, 9.5 * 10 / 12, 11.0]
    unsearched = FeedbackPlanning(2, LOW, HIGH, horizon=5, real_test=True)
    for _ in range(TEST_EPISODES):  # Q runs them, and the first search waits for them
        assert not unsearched.due(0)
        unsearched.open_episode(0)
        unsearched.close_episode(rewards[:5], ended[:5])
    assert unsearched.returns == [5.5] * TEST_EPISODES and unsearched.due(0)
    untested = FeedbackPlanning(2, LOW, HIGH, horizon=5)
    untested.open_episode(0)  # neither a test nor a policy: not recorded
    untested.close_episode(rewards[:5], ended[:5])
    assert untested.returns == [] and untested.due(0)


def test_a_search_waits_for_the_current_actors_episodes() -> None:
    planning, _, _ = _planning()
    planning.returns = [1.0] * (TEST_EPISODES - 1)
    assert not planning.due(SEARCH_EVERY)
    planning.returns.append(1.0)
    assert planning.due(SEARCH_EVERY) and not planning.due(SEARCH_EVERY - 1)
    planning.acting, planning.searched_at = False, 3 * SEARCH_EVERY  # Q acts on: data double
    assert not planning.due(6 * SEARCH_EVERY - 1) and planning.due(6 * SEARCH_EVERY)
    planning.searched_at = 0
    assert not planning.due(SEARCH_EVERY - 1) and planning.due(SEARCH_EVERY)
    planning.real_test, planning.acting = False, True
    planning.returns = []
    assert planning.due(SEARCH_EVERY)


@pytest.mark.parametrize(
    ("trial", "kept"),
    [([-5.0, -5.5], False), ([-1.1, -0.95], True), ([-1.4, -1.5, -1.45, -1.5], False),
     ([-1.4, -0.6], True)],
)  # fmt: skip
def test_weights_worse_on_the_task_give_way_to_those_before(trial: list, kept: bool) -> None:
    """Oracle: Welch's difference of the means against two of its standard errors, by
    hand (before: -1.0, -1.2, -0.9)."""
    planning, model, rng = _planning()
    before = planning.gains.copy()
    planning.kept = (before, -3.0, [-1.0, -1.2, -0.9], True)
    tried = before + 0.1
    planning.gains, planning.returns = tried, list(trial)
    old, new = np.array([-1.0, -1.2, -0.9]), np.array(trial)
    se = np.sqrt(old.var(ddof=1) / 3 + new.var(ddof=1) / len(new))
    assert (new.mean() >= old.mean() - 2.0 * se) == kept
    planning.search(model, 200, rng)  # no Adam step: the search keeps what it starts from
    assert planning.kept is None
    np.testing.assert_array_equal(planning.gains, tried if kept else before)
    assert planning.returns == (trial if kept else [-1.0, -1.2, -0.9]) and planning.acting


@pytest.mark.parametrize("kept", [False, True])
def test_a_first_policy_worse_than_q_gives_way_to_q(kept: bool) -> None:
    """The first weights a search puts in place are on trial against ``Q``'s episodes;
    if they lose, ``Q`` acts again, until a search finds other weights."""
    planning = FeedbackPlanning(2, LOW, HIGH, horizon=30, net=True, real_test=True)
    _, model, rng = _planning()
    planning.starts = rng.uniform(-0.5, 0.5, (8, 2))
    planning.gradient_settings = PolicyGradientSettings(horizon=30, steps=30, learning_rate=0.05)
    q_returns = [-2.0, -2.5]
    planning.returns = list(q_returns)
    planning.search(model, SEARCH_EVERY, rng)
    assert planning.acting and planning.kept is not None and planning.kept[3] is False
    assert planning.q_returns == q_returns  # what the model's next returns are set against
    first, tried = planning.kept[0], planning.gains.copy()
    assert -2.25 < planning.value < -1.2  # the returns below keep the model's promise
    planning.returns = [-1.2, -1.4] if kept else [-9.0, -8.0]
    planning.gradient_settings = PolicyGradientSettings(horizon=30, steps=0)
    planning.search(model, 2 * SEARCH_EVERY, rng)  # judged, then searched with no Adam step
    assert planning.kept is None and planning.acting is kept
    assert (planning.overshoot == 0.0) is kept  # -9 and -8 fell short of the promise
    np.testing.assert_array_equal(planning.gains, tried if kept else first)
    assert planning.returns == ([-1.2, -1.4] if kept else q_returns)


@pytest.mark.parametrize(("shortfall", "acting"), [([2.2, 2.4], False), ([2.5, 0.0], True),
                                                  ([0.1, -0.1], True)])  # fmt: skip
def test_the_gate_reads_the_model_less_what_it_last_promised_in_vain(
    shortfall: list, acting: bool
) -> None:
    """Oracle by hand: weights that acted and returned significantly less (two standard
    errors of their mean) than the model's score for them leave that shortfall as the
    ``overshoot``; the next search's score, less it, must beat ``Q``'s mean."""
    planning, model, rng = _planning()
    promise = planning.value
    r = promise - np.array(shortfall)
    planning.q_returns, planning.returns = [promise - 2.0] * 2, list(r)
    short = promise - r.mean()
    overshoot = short if short > 2.0 * r.std(ddof=1) / np.sqrt(len(r)) else 0.0
    planning.search(model, SEARCH_EVERY, rng)  # no Adam step: the same weights, re-scored
    assert planning.overshoot == pytest.approx(overshoot, abs=1e-12)
    assert abs(planning.value - promise) < 0.2  # fresh starts: the score moves a little
    assert planning.acting is bool(planning.value - overshoot > promise - 2.0) is acting
    assert planning.returns == (list(r) if acting else [])  # else Q's trial: returns afresh
    assert planning.q_on_trial is not acting


def test_weights_a_search_replaces_go_on_trial() -> None:
    planning, model, rng = _planning()  # the network's first weights: no force anywhere
    planning.gradient_settings = PolicyGradientSettings(horizon=30, steps=30, learning_rate=0.05)
    planning.returns = [-2.0, -2.5]
    before = planning.gains.copy()
    planning.search(model, 200, rng)
    assert not np.array_equal(planning.gains, before)  # the search moved them
    assert planning.kept is not None and planning.returns == []
    np.testing.assert_array_equal(planning.kept[0], before)
    assert planning.kept[2] == [-2.0, -2.5] and planning.kept[3] is True


def test_weights_the_model_expects_worse_than_q_do_not_replace_it() -> None:
    """While ``Q`` acts, found weights go on trial only where the model's return for them
    beats the mean of ``Q``'s returns; else ``Q`` acts on, and the next search starts
    from them."""
    planning = FeedbackPlanning(2, LOW, HIGH, horizon=30, net=True, real_test=True)
    _, model, rng = _planning()
    planning.starts = rng.uniform(-0.5, 0.5, (8, 2))
    planning.gradient_settings = PolicyGradientSettings(horizon=30, steps=30, learning_rate=0.05)
    planning.returns = [0.0, 0.0]  # no cost at all: better than any policy can do
    planning.search(model, 0, rng)
    assert planning.value < 0.0 and planning.policy is not None
    assert not planning.acting and planning.kept is None and planning.returns == [0.0, 0.0]
    found = planning.gains.copy()
    q_returns = [planning.value - 1.0, planning.value - 1.5]
    planning.returns = list(q_returns)
    planning.gradient_settings = PolicyGradientSettings(horizon=30, steps=0)
    planning.search(model, SEARCH_EVERY, rng)  # no Adam step: the same weights, expected better
    assert not planning.acting  # the weights did not move: no trial either
    planning.gradient_settings = PolicyGradientSettings(horizon=30, steps=30, learning_rate=0.05)
    planning.search(model, 2 * SEARCH_EVERY, rng)
    assert planning.acting and planning.kept is not None and planning.kept[3] is False
    np.testing.assert_array_equal(planning.kept[0], found)
    assert planning.kept[2] == planning.q_returns == q_returns


def _halting(ends_beyond: bool = False) -> tuple[FeedbackPlanning, GPDynamicsModel, float,
                                                 float]:  # fmt: skip
    """``Q`` acting on a model of the double integrator learned from states within 0.3 of
    the origin only, so that a policy's 30-step roll-outs from near its edge halt; the
    model's return for
    the weights a search from there moves to, and that return had each halt been paid
    the most reward seen (:func:`~geoq.models.rollout_outcomes`, whose halted steps
    ``tests/models/test_planner.py`` checks). ``ends_beyond``: the rewards are 1 a step
    more (so that ending costs), the termination output is 1 wherever the next state lies
    a spacing and a half or more from the data (as a walker's model that has seen only
    falls predicts a fall wherever it has no data), and the most is read with an end
    there paid as a halt."""
    rng = np.random.default_rng(0)
    S, A = rng.uniform(-0.3, 0.3, (200, 2)), rng.uniform(-1, 1, (200, 1))
    change = np.column_stack([0.1 * S[:, 1], 0.1 * A[:, 0]])
    rewards = float(ends_beyond) - S[:, 0] ** 2
    model = GPDynamicsModel(2, 1).fit(S, A, rewards, S + change, np.zeros(200), rng)
    if ends_beyond:
        predict = model.predict_mean

        def ending(states: FloatArray, actions: FloatArray) -> FloatArray:
            mean = predict(states, actions)
            beyond = model.support.distance(states + mean[:, :2]) >= 1.5
            mean[:, 3] = np.where(beyond, 1.0, mean[:, 3])
            return mean

        model.predict_mean = ending  # type: ignore[method-assign]
    planning = FeedbackPlanning(2, LOW, HIGH, horizon=30, net=True, real_test=True)
    planning.gradient_settings = PolicyGradientSettings(horizon=30, steps=30, learning_rate=0.05)
    planning.starts = rng.uniform(0.2, 0.3, (8, 2))
    found = copy.deepcopy(planning)
    found.returns = [31.0 * ends_beyond] * TEST_EPISODES  # beyond any policy: Q acts on
    found.search(model, 200, np.random.default_rng(1))
    assert found.policy is not None and not found.acting and found.kept is None
    policy, gains = found.policy, found.gains
    bounds = {}
    for trust in (True, False):
        returns, halted = rollout_outcomes(model, planning.starts,
                                           lambda t, S, rows: policy.act(gains, S), 30,
                                           gamma=1.0, noise=None, trust_ends=trust)  # fmt: skip
        bounds[trust] = returns.mean(), (returns + halted * np.ptp(model.reward_range)).mean()
    least, most = bounds[not ends_beyond]
    assert least < most - 0.5  # the halts keep the model from telling
    if ends_beyond:  # believed, the ends beyond the data would tell: too little to try
        assert bounds[True][1] < least + 0.25 * (most - least)
    return planning, model, float(least), float(most)


@pytest.mark.parametrize(("where", "tried_before", "tried"),
                         [(0.5, False, True), (0.5, True, False), (1.5, False, False),
                          (-0.5, False, True), (-0.5, True, True)])  # fmt: skip
def test_where_halts_keep_the_model_from_telling_the_task_is_asked_once(
    where: float, tried_before: bool, tried: bool
) -> None:
    """While ``Q`` acts and no policy has yet replaced it, weights a search moved that the
    model scores below ``Q``'s mean go on trial all the same where, each halt paid the
    most reward seen, it would have scored them above (``where``: ``Q``'s mean between
    the two scores, 0 at the model's, 1 at the most). Once a policy has replaced ``Q``
    (``tried_before``: ``Q``'s returns then on record), the model's score alone decides."""
    planning, model, least, most = _halting()
    q_returns = [least + where * (most - least)] * TEST_EPISODES
    planning.returns = list(q_returns)
    planning.q_returns = [least - 1.0] * TEST_EPISODES if tried_before else []
    planning.search(model, 200, np.random.default_rng(1))
    assert abs(planning.value - least) < 0.25 * (most - least)  # fresh starts: near
    assert planning.acting is tried and (planning.kept is not None) is tried
    assert planning.returns == ([] if tried else q_returns)
    if tried:
        assert planning.q_returns == q_returns and planning.kept is not None
        assert planning.kept[2] == q_returns and planning.kept[3] is False


def test_an_end_the_model_predicts_beyond_its_data_does_not_tell_either() -> None:
    """A model that ends every roll-out where it has no data scores the weights found at
    what the steps before paid, however the halts are priced, were its ends believed there;
    they are not (an end beyond the data is as unknown as the state), so with ``Q``'s mean
    halfway to the return where those halts are paid the most reward, the task is asked."""
    planning, model, least, most = _halting(ends_beyond=True)
    q_returns = [least + 0.5 * (most - least)] * TEST_EPISODES
    planning.returns = list(q_returns)
    planning.search(model, 200, np.random.default_rng(1))
    assert planning.value < q_returns[0] and planning.acting and planning.kept is not None


@pytest.mark.parametrize(("where", "ahead", "acts_on"),
                         [(0.5, True, True), (0.5, False, False), (1.5, True, False)])  # fmt: skip
def test_a_policy_ahead_of_q_on_the_task_acts_on_where_the_model_cannot_tell(
    where: float, ahead: bool, acts_on: bool
) -> None:
    """While a policy acts, a search whose weights the model scores below ``Q``'s record
    leaves the policy acting where the model cannot tell (``Q``'s mean between its score
    and the score with each halt paid the most reward seen, ``where`` as in the test
    above) and the policy's returns on the task are not below ``Q``'s record (``ahead``):
    the weights found (the search moved them) go on trial against the acting ones.
    Where the model can tell, or the task says ``Q`` did better, ``Q`` comes back on
    trial, as before."""
    planning, model, least, most = _halting()
    planning.returns = [0.0] * TEST_EPISODES  # Q's, beyond any policy: Q acts on
    planning.search(model, 200, np.random.default_rng(1))
    assert planning.policy is not None and not planning.acting and planning.kept is None
    q_mean = least + where * (most - least)
    mine = [q_mean + (0.1 if ahead else -0.1) * (most - least)] * TEST_EPISODES
    planning.acting, planning.q_returns, planning.returns = True, [q_mean] * 2, list(mine)
    before = planning.gains.copy()
    planning.search(model, 400, np.random.default_rng(2))
    assert planning.value < q_mean and planning.overshoot == 0.0  # the model: below Q
    moved = not np.array_equal(planning.gains, before)
    assert planning.q_on_trial is not acts_on and planning.acting is acts_on
    if not acts_on:  # Q's returns start afresh, set against the policy's
        assert planning.returns == [] and planning.kept is not None
        assert planning.kept[2] == mine and planning.kept[3] is True
        return
    assert moved and planning.kept is not None and planning.blind  # on trial, unscored
    assert planning.returns == [] and planning.q_returns == [q_mean] * 2
    np.testing.assert_array_equal(planning.kept[0], before)
    assert planning.kept[2] == mine and planning.kept[3] is True


@pytest.mark.parametrize(
    ("fresh", "kept"),
    [([-0.6, -0.45], False), ([-0.5, -0.5], True), ([-1.5, 0.6], True), ([-0.55, -0.52], False)],
)
def test_weights_the_model_could_not_score_are_judged_on_the_means(fresh: list, kept: bool) -> None:
    """Oracle by hand (the acting weights' mean: -0.5): weights on trial that the model
    could not score (``blind``) keep acting only where their mean is not below the
    weights' they replaced, whatever the spread (``[-0.6, -0.45]`` is within two standard
    errors, and gives way); weights the model expected to do better are given the two
    standard errors (the same returns keep them)."""
    for blind in (True, False):
        planning, model, rng = _planning()
        before = planning.gains.copy()
        planning.kept, planning.blind = (before, -3.0, [-0.5, -0.6, -0.4], True), blind
        tried = before + 0.1
        planning.gains, planning.returns = tried, list(fresh)
        planning.search(model, 200, rng)  # no Adam step: the search keeps what it starts from
        assert planning.kept is None and not planning.blind and planning.acting
        stays = kept or not blind
        np.testing.assert_array_equal(planning.gains, tried if stays else before)
        assert planning.returns == (fresh if stays else [-0.5, -0.6, -0.4])


def test_greedy_actions_follow_the_weights_before_until_unscored_ones_reach_their_mean() -> None:
    """Oracle by hand (the acting weights' mean: -0.5): while weights the model could
    not score are on trial, greedy actions follow the weights they replaced until the
    mean of their returns reaches those weights' (none yet: the weights before); weights
    the model scored follow their own from the start."""
    planning, _, rng = _planning()
    before = planning.gains.copy()
    planning.kept, planning.blind = (before, -3.0, [-0.5, -0.6, -0.4], True), True
    planning.gains = before + 0.1
    for fresh in ([], [-0.6], [-0.4, -0.7]):
        planning.returns = fresh
        np.testing.assert_array_equal(planning.greedy_weights, before)
    states = rng.uniform(-1.0, 1.0, (1, 2))
    assert planning.policy is not None
    expected = planning.policy.act(before, states)
    np.testing.assert_array_equal(planning.action(states, None), expected)
    for fresh in ([-0.5], [-0.9, 0.0]):
        planning.returns = fresh
        np.testing.assert_array_equal(planning.greedy_weights, before + 0.1)
    planning.blind, planning.returns = False, []
    np.testing.assert_array_equal(planning.greedy_weights, before + 0.1)


def _q_on_trial(on_trial: bool = False) -> tuple[FeedbackPlanning, GPDynamicsModel,
                                                   np.random.Generator, FloatArray]:  # fmt: skip
    """A policy acting with returns ``-0.5, -0.6, -0.4`` (its weights on trial, or not),
    which a search at 300 transitions sends back to ``Q`` on trial: ``Q``'s returns on
    record (0, -0.1) beat any policy's score. Also the policy's weights."""
    planning, model, rng = _planning()
    planning.returns = [-0.5, -0.6, -0.4]
    before = planning.gains.copy()
    if on_trial:  # the weights before did worse: the trial keeps the new ones
        planning.kept = (before - 0.1, -3.0, [-0.5, -0.6], True)
    planning.search(model, 200, rng)  # the model expects the same as before: they stay
    assert planning.acting and planning.kept is None and planning.returns == [-0.5, -0.6, -0.4]
    planning.q_returns = [0.0, -0.1]  # Q did better than any policy can
    planning.search(model, 300, rng)
    return planning, model, rng, before


@pytest.mark.parametrize("on_trial", [False, True])
def test_a_policy_the_model_no_longer_expects_to_beat_q_puts_q_on_trial(on_trial: bool) -> None:
    """While a policy acts (its weights on trial or not), a search whose weights the model
    scores below the mean of ``Q``'s returns on record brings ``Q`` back, on trial against
    the policy: ``Q``'s returns start afresh, and the next search comes after ``Q``'s
    episodes; it starts from the weights found."""
    planning, _, _, before = _q_on_trial(on_trial)
    assert not planning.acting and planning.q_on_trial and planning.returns == []
    assert planning.kept is not None and planning.kept[2] == [-0.5, -0.6, -0.4]
    np.testing.assert_array_equal(planning.kept[0], before)
    np.testing.assert_array_equal(planning.gains, before)  # no Adam step: the same weights
    planning.returns = [-0.2] * (TEST_EPISODES - 1)
    assert not planning.due(10_000)  # Q's episodes first
    planning.returns.append(-0.2)
    assert planning.due(300 + SEARCH_EVERY) and not planning.due(300 + SEARCH_EVERY - 1)


@pytest.mark.parametrize(
    ("fresh", "q_wins"),
    [([-0.6, -0.45], False), ([-0.5, -0.5], True), ([-1.5, 0.6], True), ([-0.55, -0.52], False)],
)
def test_q_on_trial_is_judged_on_the_means(fresh: list, q_wins: bool) -> None:
    """Oracle by hand (the policy's mean: -0.5): ``Q`` keeps acting where its fresh mean
    is not below the policy's, whatever the spread; else the policy acts again with the
    weights the task judged, ``Q``'s fresh returns become its record, and the model's
    score cannot send the policy back before the data have doubled."""
    planning, model, rng, before = _q_on_trial()
    planning.returns = list(fresh)
    assert (np.mean(fresh) >= -0.5) == q_wins
    planning.search(model, 420, rng)
    assert planning.kept is None and not planning.q_on_trial
    if q_wins:  # Q acts on, with its fresh returns, and is asked again once the data double
        assert not planning.acting and planning.returns == fresh and planning.q_lost_at == 0
        assert planning.due(840) and not planning.due(839)
        return
    assert planning.acting and planning.returns == [-0.5, -0.6, -0.4]
    assert planning.q_returns == fresh and planning.q_lost_at == 420
    np.testing.assert_array_equal(planning.gains, before)
    planning.q_returns = [0.0, -0.1]  # the model's score is below Q's again, and not asked
    planning.search(model, 839, rng)
    assert planning.acting and planning.kept is None
    planning.search(model, 840, rng)  # the data have doubled since Q lost: Q's trial again
    assert planning.q_on_trial and planning.returns == []


def test_greedy_actions_follow_q_on_trial_as_the_evidence_stands() -> None:
    """Oracle by hand (the policy's mean: -0.5): while ``Q`` is on trial, greedy actions
    are ``Q``'s unless the mean of its returns is below the policy's, then those of the
    policy's weights ``Q`` replaced (not the weights the search found), while ``Q``
    still acts: its fresh returns so far, and before the first, its record from before
    the trial (here 0 and -0.1, above the policy's)."""
    planning, _, rng, before = _q_on_trial()
    planning.gains = before + 1.0  # the weights the search found, which the next starts from
    states = rng.uniform(-1.0, 1.0, (5, 2))
    for fresh in ([], [-0.4], [-0.5], [-0.9, 0.0]):  # none yet (the record), above, tied, above
        planning.returns = fresh
        assert planning.greedy_weights is None, fresh
    for fresh in ([-0.6], [-0.4, -0.7]):
        planning.returns = fresh
        np.testing.assert_array_equal(planning.greedy_weights, before)
        assert planning.policy is not None and not planning.acting
        expected = planning.policy.act(before, states[:1])
        np.testing.assert_array_equal(planning.action(states[:1], None), expected)
    planning.q_returns = [-0.9, -0.2]  # a record below the policy's: its weights from the start
    for fresh, policy in (([], True), ([-0.5], False), ([-0.6], True)):
        planning.returns = fresh
        weights = planning.greedy_weights
        assert (weights is not None) is policy, fresh
        if policy:
            np.testing.assert_array_equal(weights, before)
    planning.q_returns = []  # no record of Q's (an older archive): Q's until it has returns
    planning.returns = []
    assert planning.greedy_weights is None
    planning.acting, planning.kept = True, None  # a policy acting: its own weights
    np.testing.assert_array_equal(planning.greedy_weights, before + 1.0)


def test_a_policy_with_no_returns_of_q_on_record_acts_on() -> None:
    """An agent saved before ``Q``'s returns were kept beside a policy's has none to set
    the model's return against: its policy acts on."""
    planning, model, rng = _planning()
    planning.returns, planning.q_returns = [-0.5, -0.6], []
    planning.search(model, 200, rng)
    assert planning.acting and planning.returns == [-0.5, -0.6]


def _spy_on_search(
    monkeypatch: pytest.MonkeyPatch,
) -> tuple[list[tuple[PolicyGradientSettings, FloatArray | None]], GPDynamicsModel,
           np.random.Generator]:  # fmt: skip
    """What each call of ``search_policy`` is handed (its settings and ``branch_from``; it
    keeps the weights it is given), a small model to search and the generator."""
    seen: list[tuple[PolicyGradientSettings, FloatArray | None]] = []

    def spy(model, policy, params, starts, rng, settings, branch_from):
        seen.append((settings, branch_from))
        return params, 0.0

    monkeypatch.setattr(policy_planning, "search_policy", spy)
    rng = np.random.default_rng(0)
    S = rng.uniform(-1, 1, (50, 2))
    model = GPDynamicsModel(2, 1).fit(S, rng.uniform(-1, 1, (50, 1)), -S[:, 0] ** 2, S,
                                      np.zeros(50), rng)  # fmt: skip
    return seen, model, rng


@pytest.mark.parametrize(("horizon", "branch", "steps"), [(10, 10, 10), (200, 30, 200),
                                                          (1000, 30, 400)])  # fmt: skip
def test_a_net_search_branches_short_roll_outs_capped_by_its_horizon(
    monkeypatch, horizon, branch, steps
) -> None:
    """The branched search's roll-outs and Adam steps never exceed the search's horizon
    (:data:`~geoq.agents.policy_planning.BRANCH`), and it climbs from the stored states
    it is given."""
    planning = FeedbackPlanning(2, LOW, HIGH, horizon=horizon, net=True, real_test=True)
    c = planning.gradient_settings
    assert (c.horizon, c.branch_horizon, c.steps) == (horizon, branch, steps)
    assert c.particles == BRANCH.particles
    seen, model, rng = _spy_on_search(monkeypatch)
    planning.starts, planning.returns = np.zeros((1, 2)), [0.0] * TEST_EPISODES
    states = np.arange(10.0).reshape(5, 2)
    planning.search(model, 0, rng, states)
    assert len(seen) == 1 and seen[0][0].branch_horizon == branch and seen[0][1] is states


def test_a_net_search_is_paid_for_by_the_transitions_since_the_last(monkeypatch) -> None:
    """A search may ask the model for :data:`~geoq.agents.policy_planning.SEARCH_WORK`
    per transition stored since the last search, never more than the settings' budget:
    searches that come often, or find nothing, cannot add up past it."""
    planning = FeedbackPlanning(2, LOW, HIGH, horizon=30, net=True, real_test=True)
    seen, model, rng = _spy_on_search(monkeypatch)
    planning.starts = np.zeros((1, 2))
    full = planning.gradient_settings.budget / SEARCH_WORK
    for n in (200, 300, 300 + int(2 * full)):
        planning.returns = [0.0] * TEST_EPISODES
        planning.search(model, n, rng)
    budgets = [settings.budget for settings, _ in seen]
    assert budgets == [200 * SEARCH_WORK, 100 * SEARCH_WORK, planning.gradient_settings.budget]
    assert planning.gradient_settings.budget == BRANCH.budget  # the settings kept as they are
