"""Video frames: the Mountain Car painter against Gymnasium's own render, and the packed pixels' conversions
against Pillow's and ffmpeg's."""

from __future__ import annotations

import subprocess

import gymnasium as gym
import imageio_ffmpeg
import numpy as np
import pytest
from PIL import Image

from rlcompare.envs.registry import environment
from rlcompare.report import frames, video


@pytest.mark.slow("compiles or trains for a second or more")
def test_the_painter_draws_gymnasiums_frame_pixel_for_pixel() -> None:
    env = gym.make("MountainCar-v0", render_mode="rgb_array")
    env.reset(seed=0)
    car = env.unwrapped
    painter = environment("MountainCar-v0").painter(car)
    painted = np.empty((car.screen_height, car.screen_width), dtype=np.uint32)
    rng = np.random.default_rng(1)
    edges = [car.min_position, car.max_position, car.goal_position, car.goal_position - 0.02, -np.pi / 6]
    for step in range(300):  # steps, and jumps that leave the last car far away
        if step < len(edges):
            car.state = np.array([edges[step], 0.0])
        elif step % 3:
            env.step(int(rng.integers(3)))
        else:
            car.state = np.array([rng.uniform(car.min_position, car.max_position), 0.0])
        painter.paint(painted)
        np.testing.assert_array_equal(frames.unpack(painted), env.render(), err_msg=f"step {step}")
    env.close()


def test_packing_keeps_every_pixel() -> None:
    rgb = np.random.default_rng(0).integers(0, 256, (6, 10, 3), dtype=np.uint8)
    packed = frames.pack(rgb)
    assert packed.dtype == np.uint32
    assert packed.shape == (6, 10)
    assert packed[0, 0] == (int(rgb[0, 0, 0]) << 16) + (int(rgb[0, 0, 1]) << 8) + int(rgb[0, 0, 2])
    np.testing.assert_array_equal(frames.unpack(packed), rgb)
    np.testing.assert_array_equal(np.asarray(frames.image(packed)), rgb)


def ffmpeg_yuv420(rgb: np.ndarray) -> np.ndarray:
    """ffmpeg's own conversion of RGB frames ``(n, h, w, 3)`` to ``yuv420p``, one row of planes a frame."""
    n, height, width, _ = rgb.shape
    out = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-loglevel", "error", "-f", "rawvideo", "-pix_fmt",
                          "rgb24", "-s", f"{width}x{height}", "-i", "-", "-f", "rawvideo", "-pix_fmt", "yuv420p", "-"],
                         input=rgb.tobytes(), capture_output=True, check=True).stdout
    return np.frombuffer(out, dtype=np.uint8).reshape(n, -1)


def ours(rgb: np.ndarray) -> np.ndarray:
    planes = np.empty((len(rgb), rgb[0].size // 2), dtype=np.uint8)
    for frame, out in zip(rgb, planes, strict=True):
        frames.yuv420(frames.pack(frame), out)
    return planes


def test_yuv420_is_ffmpegs_bt601_conversion_to_one_level() -> None:
    colours = np.random.default_rng(0).integers(0, 256, (64, 3), dtype=np.uint8)
    colours[:4] = [(0, 0, 0), (255, 255, 255), (255, 0, 0), (0, 0, 255)]
    flat = np.broadcast_to(colours[:, None, None, :], (64, 8, 8, 3)).copy()  # one colour a frame
    assert np.abs(ours(flat).astype(int) - ffmpeg_yuv420(flat)).max() <= 1
    black, white = ours(flat[:2])
    assert (black[:64] == 16).all()
    assert (white[:64] == 235).all()
    assert (black[64:] == 128).all()


def test_yuv420_takes_each_chroma_sample_from_its_2x2_block() -> None:
    checker = np.zeros((1, 4, 4, 3), dtype=np.uint8)
    checker[0, ::2, ::2] = checker[0, 1::2, 1::2] = (255, 0, 0)  # red and black in every 2x2 block
    mean = np.full((1, 4, 4, 3), (128, 0, 0), dtype=np.uint8)  # (255 + 0 + 255 + 0 + 2) >> 2
    luma, chroma = slice(0, 16), slice(16, 24)
    np.testing.assert_array_equal(ours(checker)[0, chroma], ours(mean)[0, chroma])
    assert set(ours(checker)[0, luma]) == {16, 82}


def test_halved_is_pillows_box_reduction() -> None:
    rgb = np.random.default_rng(2).integers(0, 256, (40, 60, 3), dtype=np.uint8)
    pillow = Image.fromarray(rgb).resize((30, 20), Image.Resampling.BOX, reducing_gap=1.0)
    np.testing.assert_array_equal(frames.unpack(frames.halved(frames.pack(rgb))), np.asarray(pillow))


def test_an_environment_without_a_painter_shows_its_own_render() -> None:
    class Left:
        def act(self, observation: np.ndarray) -> int:
            return 0

    assert environment("CartPole-v1").painter is None
    episode = video.record_episode(Left(), episode_seed=4, max_steps=6, env_id="CartPole-v1")
    env = gym.make("CartPole-v1", render_mode="rgb_array", max_episode_steps=6)
    env.reset(seed=4)
    expected = [env.render()]
    for _ in range(episode.length):
        env.step(0)
        expected.append(env.render())
    env.close()
    assert len(episode.frames) == len(expected) > 1
    for ours, theirs in zip(episode.frames, expected, strict=True):
        np.testing.assert_array_equal(ours, theirs)
