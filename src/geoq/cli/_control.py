"""``geoq train``, ``geoq evaluate`` and ``geoq bench-control``: the control agent."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from geoq.cli._common import (
    BENCHMARK_OVERWRITE_OPTION,
    CONFIG_OPTION,
    OVERWRITE_OPTION,
    Backend,
    BackendOption,
    BaselinesOption,
    JobsOption,
    KernelChoice,
    SchedulerOption,
    agent_config,
    capped_jobs,
    check_agents,
    check_choices,
    check_env,
    check_out,
    check_scheduler,
    check_video_path,
    one_line,
    reported,
)

__all__ = ["bench_control", "control_suite", "evaluate", "train"]


def train(
    env: Annotated[str, typer.Option("--env", help="Gymnasium id of the task.")] = (
        "geoq/PendulumSwingUp-v0"
    ),
    kernel: Annotated[
        KernelChoice, typer.Option("--kernel", help="Kernel of the GP Q-function.")
    ] = KernelChoice.euclidean,
    timesteps: Annotated[
        int, typer.Option("--timesteps", min=1, help="Environment steps to learn for.")
    ] = 2_000,
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of every random choice.")] = 0,
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            file_okay=False,
            help=(
                "Output directory: learning_curve.csv (training episodes), evaluations.csv "
                "(greedy evaluations), learning_curve.png (both), agent.npz, config.json."
            ),
        ),
    ] = Path("results/train"),
    config: Annotated[Path | None, CONFIG_OPTION] = None,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Show a progress bar on stderr.")
    ] = True,
    eval_every: Annotated[
        int,
        typer.Option(
            "--eval-every",
            min=0,
            help=(
                "Greedy evaluations every N steps (at the end of the episode that reaches "
                "them) and after the last step; 0: none. They do not change the learning."
            ),
        ),
    ] = 250,
    eval_episodes: Annotated[
        int, typer.Option("--eval-episodes", min=1, help="Episodes per greedy evaluation.")
    ] = 10,
    overwrite: Annotated[bool, OVERWRITE_OPTION] = False,
) -> None:
    """Learn to control a task online with a GP Q-function agent (GPQAgent)."""
    from geoq.experiments.control.training import TRAIN_FILES

    check_out(out, TRAIN_FILES, overwrite)
    overrides = agent_config(config)
    check_agents(env, [kernel.value], [overrides])
    with reported("train", "nothing was written"):
        from geoq.experiments.control.training import train as run_train

        agent = run_train(
            env, out, kernel=kernel.value, timesteps=timesteps, seed=seed, progress=progress,
            eval_every=eval_every, eval_episodes=eval_episodes, overwrite=overwrite,
            **overrides,
        )  # fmt: skip
    last = agent.episodes[-1] if agent.episodes else None
    tail = f"; last episode return {last.ret:.1f}" if last else ""
    typer.echo(f"geoq train: {agent.num_timesteps} steps, {len(agent.episodes)} episodes{tail}; "
               f"results in {out}")  # fmt: skip


def evaluate(
    agent_path: Annotated[
        Path,
        typer.Argument(metavar="AGENT", exists=True, dir_okay=False, help="A saved agent.npz."),
    ],
    episodes: Annotated[
        int, typer.Option("--episodes", min=1, help="Number of evaluation episodes.")
    ] = 20,
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the episodes' resets.")] = 0,
    env: Annotated[
        str | None, typer.Option("--env", help="Gymnasium id (default: the agent's own).")
    ] = None,
    video: Annotated[
        Path | None,
        typer.Option(
            "--video",
            metavar="FILE.gif",
            dir_okay=False,
            help=(
                "Also write one greedy episode as an animated GIF (the first evaluation "
                "episode of --seed, a frame per step at the env's render_fps). Needs an env "
                "with render_mode 'rgb_array' (geoq/PendulumSwingUp-v0, geoq/TwoRooms-v0)."
            ),
        ),
    ] = None,
) -> None:
    """Evaluate a saved agent: mean return with its 95% interval, and the success rate."""
    if video is not None:
        check_video_path(video)
    if env is not None:
        check_env(env)
    from geoq._io import ArchiveError
    from geoq.agents import GPQAgent

    try:
        agent = GPQAgent.load(agent_path, env=env)
    except ArchiveError as exc:
        raise typer.BadParameter(one_line(exc), param_hint="'AGENT'") from exc
    except ValueError as exc:  # the env's spaces differ from the agent's
        raise typer.BadParameter(one_line(exc), param_hint="'--env'") from exc
    if agent.env is None:
        raise typer.BadParameter(
            f"the agent's env {agent.env_id or '(unnamed)'!r} is not registered here; pass "
            "--env ID of a registered env with the agent's spaces",
            param_hint="'--env'",
        )
    if video is not None:
        from geoq.experiments.control.video import check_renderable

        try:
            check_renderable(env or agent.env_id)
        except ValueError as exc:
            raise typer.BadParameter(one_line(exc), param_hint="'--video'") from exc
    with reported("evaluate", "nothing was written"):
        from geoq.experiments.control.evaluation import evaluate_agent

        result = evaluate_agent(agent, env, episodes, seed)
    typer.echo(result.summary())
    if video is not None:
        with reported("evaluate", f"{video} was not written"):
            from geoq.experiments.control.video import record_episode, write_gif

            episode = record_episode(agent, env, seed)
            write_gif(video, episode.frames, episode.fps)
        typer.echo(f"video: {video} ({len(episode.frames)} frames at {episode.fps:g} fps, "
                   f"return {episode.ret:.1f})")  # fmt: skip


def bench_control(
    out: Annotated[Path, typer.Option("--out", file_okay=False, help="Output directory.")] = Path(
        "results/control"
    ),
    env: Annotated[str, typer.Option("--env", help="Gymnasium id of the task.")] = (
        "geoq/PendulumSwingUp-v0"
    ),
    kernels: Annotated[
        list[KernelChoice] | None,
        typer.Option("--kernel", help="Kernel(s) to compare (repeat the option)."),
    ] = None,
    explorations: Annotated[
        list[str] | None,
        typer.Option(
            "--exploration",
            help="Exploration mode(s) to compare: ucb, thompson, gaussian (repeat the option).",
        ),
    ] = None,
    replays: Annotated[
        list[str] | None,
        typer.Option(
            "--replay",
            help="Replay mode(s) to compare: none, uniform, graph (repeat the option).",
        ),
    ] = None,
    baselines: BaselinesOption = None,
    seeds: Annotated[int, typer.Option("--seeds", min=1, help="Seeds per setting.")] = 10,
    timesteps: Annotated[int, typer.Option("--timesteps", min=1, help="Steps per run.")] = 3_000,
    eval_every: Annotated[
        int, typer.Option("--eval-every", min=1, help="Steps between evaluations.")
    ] = 250,
    eval_episodes: Annotated[
        int, typer.Option("--eval-episodes", min=1, help="Episodes per evaluation.")
    ] = 20,
    jobs: JobsOption = 1,
    backend: BackendOption = Backend.loky,
    scheduler: SchedulerOption = None,
    config: Annotated[Path | None, CONFIG_OPTION] = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress")] = True,
    overwrite: Annotated[bool, BENCHMARK_OVERWRITE_OPTION] = False,
) -> None:
    """Benchmark the agent: steps to success, kernels x exploration x replay x seeds (resumable)."""
    from geoq.agents.acquisition import EXPLORATION_MODES
    from geoq.agents.config import REPLAYS
    from geoq.experiments.control.baselines import BASELINES
    from geoq.experiments.control.benchmark import check_baselines, check_benchmark_dir

    check_scheduler(scheduler, backend)
    check_choices(explorations, EXPLORATION_MODES, "--exploration")
    check_choices(replays, REPLAYS, "--replay")
    check_choices(baselines, BASELINES, "--baseline")
    try:
        check_baselines(baselines or [])
    except ValueError as exc:
        raise typer.BadParameter(one_line(exc), param_hint="'--baseline'") from exc
    check_out(out)
    base = agent_config(config)
    configs = [dict(base, exploration=m) for m in explorations] if explorations else [base]
    if replays:
        configs = [dict(c, replay=r) for c in configs for r in replays]
    names = [k.value for k in (kernels or [KernelChoice.euclidean])]
    check_agents(env, names, configs)
    settings = {
        "env": env, "kernels": names, "seeds": seeds, "timesteps": timesteps,
        "eval_every": eval_every, "eval_episodes": eval_episodes, "configs": configs,
        "baselines": baselines or [],
    }  # fmt: skip
    try:
        check_benchmark_dir(out, settings, overwrite)
    except OSError as exc:
        text = str(exc).replace("overwrite=True (--overwrite)", "--overwrite")
        raise typer.BadParameter(text, param_hint="'--out'") from exc
    jobs = capped_jobs(jobs, scheduler)
    with reported("bench-control", "finished cells are kept; rerun to resume"):
        from geoq.experiments.control.benchmark import run_control_benchmark

        run_control_benchmark(
            out, env_id=env, kernels=names, seeds=seeds, timesteps=timesteps,
            eval_every=eval_every, eval_episodes=eval_episodes, configs=configs,
            baselines=baselines or [], jobs=jobs, backend=backend.value, scheduler=scheduler,
            progress=progress, overwrite=overwrite,
        )  # fmt: skip
    typer.echo(f"geoq bench-control: done; {out / 'CONTROL.md'}")


def control_suite(
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            file_okay=False,
            help="Output directory: CONTROL_SUITE.md, control_suite.json and one benchmark "
            "directory per task (finished cells are kept: rerun to resume).",
        ),
    ] = Path("results/control-suite"),
    tasks: Annotated[
        list[str] | None,
        typer.Option(
            "--task",
            help="Task id (repeat the option; default: every task this machine can run: "
            "geoq/PendulumSwingUp-v0, MountainCarContinuous-v0, Pendulum-v1, geoq/TwoRooms-v0, "
            "and with the mujoco extra InvertedPendulum-v5 and Reacher-v5).",
        ),
    ] = None,
    seeds: Annotated[
        int | None,
        typer.Option(
            "--seeds",
            min=1,
            help="Seeds per task instead of each protocol's (an indicative run; the report "
            "says so).",
        ),
    ] = None,
    baselines: BaselinesOption = None,
    jobs: JobsOption = 1,
    backend: BackendOption = Backend.loky,
    scheduler: SchedulerOption = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress")] = True,
    overwrite: Annotated[bool, BENCHMARK_OVERWRITE_OPTION] = False,
) -> None:
    """The control tasks, each under its protocol and goal: CONTROL_SUITE.md (resumable)."""
    from geoq.experiments.control.baselines import BASELINES
    from geoq.experiments.control.benchmark import check_baselines
    from geoq.experiments.control.suite import control_goals, run_control_suite

    check_scheduler(scheduler, backend)
    check_choices(baselines, BASELINES, "--baseline")
    try:
        check_baselines(baselines or [])
    except ValueError as exc:
        raise typer.BadParameter(one_line(exc), param_hint="'--baseline'") from exc
    try:
        control_goals(tasks)
    except ValueError as exc:
        raise typer.BadParameter(one_line(exc), param_hint="'--task'") from exc
    check_out(out)
    jobs = capped_jobs(jobs, scheduler)
    with reported("control-suite", "finished cells are kept; rerun to resume"):
        run_control_suite(
            out, tasks, seeds=seeds, baselines=baselines or [], jobs=jobs,
            backend=backend.value, scheduler=scheduler, progress=progress, overwrite=overwrite,
        )  # fmt: skip
    typer.echo(f"geoq control-suite: done; {out / 'CONTROL_SUITE.md'}")
