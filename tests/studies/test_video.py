"""Videos of the greedy agents: Gymnasium's frames, captions, MP4 and GIF files, one video per stage."""

from __future__ import annotations

import dataclasses
import gc
import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
import pytest
from PIL import Image, ImageSequence

from rlcompare import ExperimentConfig, load_agent, run
from rlcompare.report import captions, encode, video

MAX_STEPS = 200


class Pump:
    """Push the way the car moves: a hand-made policy that reaches the flag in about 100 steps."""

    def act(self, observation: np.ndarray) -> int:
        return 2 if observation[1] >= 0 else 0


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("video") / "q_learning-decay"
    run(ExperimentConfig(algorithm="q_learning", schedule="decay", seeds=(0,), episodes=300, eval_every=0,
                         max_steps=MAX_STEPS), out=out)
    return out


@pytest.fixture(scope="module")
def pump_episode() -> video.Episode:
    return video.record_episode(Pump(), episode_seed=3, max_steps=MAX_STEPS, title="Pump · test", seed=0,
                                env_id="MountainCar-v0")


def read_mp4(path: Path) -> tuple[dict, np.ndarray]:
    """Metadata and frames of an MP4, read back with imageio's ffmpeg plugin.

    imageio-ffmpeg (0.8.1) leaves its pipes to ffmpeg open when ffmpeg has finished before the reader is
    closed (always once the stream is read to its end); the garbage collector then closes them with a
    ResourceWarning, an error under this project's ``filterwarnings``. Only that warning, from this reader,
    is ignored here; the pipes are collected before the filter is lifted.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        with imageio.get_reader(path, "FFMPEG") as reader:
            meta = reader.get_meta_data()
            frames = np.stack(list(reader.iter_data()))
        del reader
        gc.collect()
    return meta, frames


def plain_episode(agent, episode_seed: int, max_steps: int) -> tuple[float, int, bool]:
    """Return, length and termination of the same agent in Gymnasium without rendering."""
    env = gym.make("MountainCar-v0", max_episode_steps=max_steps)
    observation, _ = env.reset(seed=episode_seed)
    total, length, terminated, truncated = 0.0, 0, False, False
    while not (terminated or truncated):
        observation, reward, terminated, truncated, _ = env.step(agent.act(observation))
        total, length = total + float(reward), length + 1
    env.close()
    return total, length, bool(terminated)


def test_record_episode_keeps_gymnasiums_frames_and_return(run_dir: Path) -> None:
    agent = load_agent(run_dir, seed=0, stage="final")
    episode = video.record_episode(agent, episode_seed=11, max_steps=MAX_STEPS, env_id="MountainCar-v0")
    assert len(episode.frames) == episode.length + 1 == len(episode.returns)
    assert all(frame.shape == (400, 600, 3) and frame.dtype == np.uint8 for frame in episode.frames)
    assert (episode.episode_return, episode.length, episode.terminated) == plain_episode(agent, 11, MAX_STEPS)
    np.testing.assert_array_equal(episode.returns, -np.arange(episode.length + 1))  # -1 per step
    assert not np.array_equal(episode.frames[0], episode.frames[-1])  # the car moved


def test_a_terminated_episode_is_recorded_to_the_flag(pump_episode: video.Episode) -> None:
    assert pump_episode.terminated
    assert pump_episode.length < MAX_STEPS
    assert (pump_episode.episode_return, pump_episode.length, True) == plain_episode(Pump(), 3, MAX_STEPS)
    assert len(pump_episode.frames) == pump_episode.length + 1


def test_caption_changes_the_strip_only(pump_episode: video.Episode) -> None:
    raw = video.record_episode(Pump(), episode_seed=3, max_steps=MAX_STEPS, env_id="MountainCar-v0")
    strip = captions.CAPTION_HEIGHT
    for captioned, frame in zip(pump_episode.frames, raw.frames, strict=True):
        assert captioned.shape == (400 + strip, 600, 3)
        np.testing.assert_array_equal(captioned[strip:], frame)
    first, last = pump_episode.frames[0], pump_episode.frames[-1]
    assert (first[:strip] < 128).any()  # dark text on the light strip
    assert not np.array_equal(first[:strip], last[:strip])  # the return and the step move on

    frame = raw.frames[0]
    blank = captions.add_caption(frame, "")
    text = captions.add_caption(frame, "SARSA · ε decay · middle (episode 2500) · return -143", "seed 0")
    differs = (blank != text).any(axis=(1, 2))
    assert differs[:strip].any()
    assert not differs[strip:].any()
    assert captions._missing_glyphs(17) == ()  # ε is drawn, not a missing-glyph box


def test_stage_titles_name_algorithm_schedule_stage_and_episode() -> None:
    assert captions.stage_title(ExperimentConfig(), "middle") == "Q-Learning · ε decay · middle (episode 2500)"
    sarsa = ExperimentConfig(algorithm="sarsa", schedule="constant", episodes=1000)
    assert captions.stage_title(sarsa, "early") == "SARSA · ε = 0.5 · early (episode 100)"
    assert captions.stage_title(ExperimentConfig(algorithm="random"), None) == "Random · uniform actions"


@pytest.mark.slow("renders videos")
def test_mp4_is_h264_with_every_frame(tmp_path: Path, pump_episode: video.Episode) -> None:
    path = encode.write_mp4(pump_episode.frames, tmp_path / "pump.mp4")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pump.mp4"]  # no temporary file left
    meta, frames = read_mp4(path)
    assert meta["codec"] == "h264"
    assert meta["pix_fmt"].startswith("yuv420p")
    assert meta["size"] == (600, 448)
    assert meta["fps"] == encode.FPS
    assert frames.shape == (len(pump_episode.frames), 448, 600, 3)
    assert np.abs(frames[-1].astype(int) - pump_episode.frames[-1]).mean() < 3  # same picture, RGB order
    data = path.read_bytes()
    assert data.index(b"moov") < data.index(b"mdat")  # +faststart: playable while it downloads


def test_gif_is_smaller_and_loops(tmp_path: Path, pump_episode: video.Episode) -> None:
    path = encode.write_gif(pump_episode.frames, tmp_path / "pump.gif")
    n, every = len(pump_episode.frames), encode.GIF_EVERY
    with Image.open(path) as gif:
        assert gif.size == (300, 224)
        assert gif.n_frames == len(range(0, n, every)) + ((n - 1) % every > 0)  # every few frames, and the last
        assert gif.info["loop"] == 0
        durations = [frame.info["duration"] for frame in ImageSequence.Iterator(gif)]
    shown = 100 * every / encode.FPS  # centiseconds, the unit of GIF delays
    assert set(durations[:-1]) <= {10 * math.floor(shown), 10 * math.ceil(shown)}
    assert sum(durations) == round(1000 * n / encode.FPS, -1) + encode.GIF_HOLD_MS  # real time, then a pause
    assert 0 < path.stat().st_size < 2_000_000


@pytest.mark.slow("renders videos")
def test_writes_are_atomic_and_sizes_made_even(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    odd = [rng.integers(0, 256, (17, 31, 3), dtype=np.uint8) for _ in range(3)]
    path = encode.write_mp4(odd, tmp_path / "odd.mp4")
    meta, frames = read_mp4(path)
    assert meta["size"] == (32, 18)
    assert frames.shape == (3, 18, 32, 3)

    def broken():
        yield odd[0]
        raise RuntimeError("renderer died")

    for write in (encode.write_mp4, encode.write_gif):
        with pytest.raises(RuntimeError, match="renderer died"):
            write(broken(), tmp_path / "broken.out")
    with pytest.raises(ValueError, match="uint8"):
        encode.write_mp4([np.zeros((4, 4, 3))], tmp_path / "float.mp4")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["odd.mp4"]


@pytest.mark.slow("renders videos")
def test_stage_videos_are_one_video_per_stage(tmp_path: Path, run_dir: Path) -> None:
    paths = video.render_videos(video.plan_stage_videos(run_dir, tmp_path / "all", seed=0, max_steps=40))
    stems = [f"q_learning-decay-seed0-{stage}" for stage in ("early", "middle", "final")]
    assert [p.name for p in paths] == [f"{stem}.{ext}" for stem in stems for ext in ("mp4", "gif")]
    assert sorted(p.name for p in (tmp_path / "all").iterdir()) == sorted(p.name for p in paths)
    meta, shown = read_mp4(paths[0])
    assert shown.shape[0] == 21  # truncated at 40 steps: steps 0, 2, ..., 40
    assert meta["fps"] == encode.FPS / encode.MP4_EVERY  # every second step, in real time

    again = video.render_videos(video.plan_stage_videos(run_dir, tmp_path / "middle", seed=0, stages=["middle"],
                                                        max_steps=40, gif=False))
    assert [p.name for p in again] == [f"{stems[1]}.mp4"]
    assert again[0].read_bytes() == paths[2].read_bytes()  # the same video whatever else is rendered

    with pytest.raises(KeyError, match="stage"):
        video.plan_stage_videos(run_dir, tmp_path / "x", seed=0, stages=["late"])
    with pytest.raises(KeyError, match="seed"):
        video.plan_stage_videos(run_dir, tmp_path / "x", seed=5)


@pytest.mark.slow("renders videos")
def test_a_stage_video_shows_every_second_step_and_its_gif_every_third(tmp_path: Path, run_dir: Path) -> None:
    """Only the steps the MP4 or the GIF shows are drawn: the MP4 holds every second step's frame (and the last),
    the GIF is the one :func:`~rlcompare.report.encode.write_gif` makes of every frame of the episode."""
    job = video.plan_stage_videos(run_dir, tmp_path, seed=0, stages=["final"], max_steps=41)[0]
    mp4, gif = video.render_job(job)
    episode = video.record_episode(load_agent(run_dir, seed=0, stage="final"), episode_seed=job.episode_seed,
                                   max_steps=41, title=job.title, seed=0, env_id=job.env_id)
    assert episode.length == 41  # truncated at an odd step: its frame ends the MP4 too
    shown = read_mp4(mp4)[1]
    steps = [*range(0, 41, encode.MP4_EVERY), 41]
    assert len(shown) == len(steps)
    for frame, step in zip(shown, steps, strict=True):
        assert np.abs(frame.astype(int) - episode.frames[step]).mean() < 3
    assert gif.read_bytes() == encode.write_gif(episode.frames, tmp_path / "all.gif").read_bytes()


@pytest.mark.slow("renders videos")
def test_workers_write_the_same_files_as_one_process(tmp_path: Path, run_dir: Path) -> None:
    def plan(out: Path) -> list[video.VideoJob]:
        return video.plan_stage_videos(run_dir, out, seed=0, stages=["early", "final"], max_steps=40)

    serial = video.render_videos(plan(tmp_path / "serial"), workers=1)
    parallel = video.render_videos(plan(tmp_path / "parallel"), workers=2)
    stems = ["q_learning-decay-seed0-early", "q_learning-decay-seed0-final"]
    assert [p.name for p in parallel] == [p.name for p in serial] == [f"{s}.{e}" for s in stems for e in ("mp4", "gif")]
    assert [p.read_bytes() for p in parallel] == [p.read_bytes() for p in serial]
    assert serial[0].read_bytes() != serial[2].read_bytes()  # two different videos, not one twice
    assert sorted(p.name for p in (tmp_path / "parallel").iterdir()) == sorted(p.name for p in parallel)

    for workers in (1, 2):  # a worker's error is raised as it is in this process
        out = tmp_path / f"bad{workers}"
        good = plan(out)[0]
        bad = dataclasses.replace(good, stage="late", mp4=out / "late.mp4", gif=None)
        with pytest.raises(KeyError, match="stage 'late' is not in this run"):
            video.render_videos([good, bad], workers=workers)
        assert not (out / "late.mp4").exists()
        assert not list(out.glob(".*tmp*"))  # no temporary file left
    with pytest.raises(ValueError, match="workers"):
        video.render_videos([good], workers=0)


@pytest.mark.slow("renders videos")
def test_random_baseline_gets_one_video(tmp_path: Path) -> None:
    run(ExperimentConfig(algorithm="random", seeds=(2,), episodes=10, eval_every=0, max_steps=30),
        out=tmp_path / "random")
    paths = video.render_videos(video.plan_stage_videos(tmp_path / "random", tmp_path / "videos", seed=2))
    assert [p.name for p in paths] == ["random-seed2.mp4", "random-seed2.gif"]
    assert read_mp4(paths[0])[1].shape[0] == 16  # 30 steps: steps 0, 2, ..., 30


def test_rendering_needs_no_display_and_sets_it_up_lazily(tmp_path: Path) -> None:
    script = (
        "import os, sys\n"
        "import rlcompare.report.video as video\n"
        "assert 'SDL_VIDEODRIVER' not in os.environ and 'pygame' not in sys.modules\n"
        "class Idle:\n"
        "    def act(self, observation):\n"
        "        return 1\n"
        "episode = video.record_episode(Idle(), episode_seed=0, max_steps=3, env_id='MountainCar-v0')\n"
        "assert os.environ['SDL_VIDEODRIVER'] == 'dummy' and 'pygame' in sys.modules\n"
        "print(len(episode.frames))\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("SDL_VIDEODRIVER", "DISPLAY", "WAYLAND_DISPLAY",
                                                             "PYGAME_HIDE_SUPPORT_PROMPT")}
    result = subprocess.run([sys.executable, "-W", "error", "-c", script], env=env, capture_output=True,
                            text=True, timeout=120, cwd=tmp_path, check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout == "4\n"  # no pygame banner


def test_rendering_through_gymnasium_needs_no_sound_card_and_prints_nothing(tmp_path: Path) -> None:
    """Acrobot is drawn by ``env.render()``, whose ``pygame.init()`` also opens the sound device: on a machine
    without one, ALSA had printed a dozen lines of errors into every report."""
    script = (
        "import os\n"
        "import rlcompare.report.video as video\n"
        "class Idle:\n"
        "    def act(self, observation):\n"
        "        return 1\n"
        "episode = video.record_episode(Idle(), episode_seed=0, max_steps=3, env_id='Acrobot-v1')\n"
        "assert os.environ['SDL_AUDIODRIVER'] == 'dummy'\n"
        "print(len(episode.frames))\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith(("SDL_", "PYGAME_"))}
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120,
                            cwd=tmp_path, check=False)
    assert result.returncode == 0, result.stderr
    assert (result.stdout, result.stderr) == ("4\n", "")
