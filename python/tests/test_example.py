"""The example python/examples/tum_integrate.py on a synthetic TUM RGB-D folder: its .bt equals
`octovk integrate DIR` byte for byte, its picture is a PNG that carries its numbers, and
read_depth_png reads back the 16-bit PNGs it and the folder use exactly."""

import os
import subprocess
import sys

import numpy as np

import octovk
from conftest import run, tool

EXAMPLES = os.path.join(os.path.dirname(__file__), "..", "examples")
sys.path.insert(0, EXAMPLES)
from tum_integrate import write_png  # noqa: E402


def make_folder(root):
    """Four 64x48 views of a wall with a box in front, from a camera moving along x."""
    os.makedirs(root / "depth")
    depth_lines, pose_lines = ["# timestamp filename"], ["# timestamp tx ty tz qx qy qz qw"]
    v, u = np.mgrid[0:48, 0:64]
    for i in range(4):
        t = 100.0 + 0.1 * i
        depth = np.full((48, 64), 10000, np.uint16)  # 2 m at 1/5000 m
        depth[(u > 20 + 3 * i) & (u < 40 + 3 * i) & (v > 15)] = 7000
        depth[:2, :] = 0  # no depth
        name = f"depth/{t:.6f}.png"
        write_png(root / name, depth)
        depth_lines.append(f"{t:.6f} {name}")
        yaw = 0.05 * i
        pose_lines.append(f"{t:.6f} {0.2 * i:.4f} 0.1 1.2 0 {np.sin(yaw / 2):.7f} 0 "
                          f"{np.cos(yaw / 2):.7f}")
    (root / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    (root / "groundtruth.txt").write_text("\n".join(pose_lines) + "\n")


def test_example_writes_what_octovk_integrate_writes(context, tmp_path):
    folder = tmp_path / "tum"
    make_folder(folder)
    frames = octovk.read_tum_sequence(folder)
    assert len(frames) == 4
    again = octovk.read_depth_png(frames[1][1])
    assert again.dtype == np.uint16 and again.shape == (48, 64) and again[0, 0] == 0
    assert again[47, 30] == 7000 and again[47, 63] == 10000

    options = ["--resolution", "0.05", "--max-range", "3", "--intrinsics", "60", "60", "31.5",
               "23.5"]
    # A deprecated octovk name on the example's own lines is an error (its warnings are
    # attributed to __main__).
    strict = dict(os.environ, PYTHONWARNINGS="error::DeprecationWarning:__main__")
    out = run([sys.executable, os.path.join(EXAMPLES, "tum_integrate.py"), str(folder), "-o",
               str(tmp_path / "example.bt"), "--picture", str(tmp_path / "top.png"), *options],
              env=strict)
    assert "4 images with a pose" in out and "wrote" in out
    run([tool("OCTOVK_CLI"), "integrate", str(folder), "-o", str(tmp_path / "cli.bt"), *options])
    assert (tmp_path / "example.bt").read_bytes() == (tmp_path / "cli.bt").read_bytes()
    # The picture is large enough to read (it was 63x63 px of grey) and carries its numbers: the
    # size and heights it reports, axes and a colour bar drawn beside the view.
    import cairo
    picture = cairo.ImageSurface.create_from_png(str(tmp_path / "top.png"))
    width, height = picture.get_width(), picture.get_height()
    assert width >= 500 and height >= 300, (width, height)
    assert f"{width}x{height} px" in out and "heights" in out and " m" in out
    pixels = np.ndarray((height, picture.get_stride() // 4), np.uint32, picture.get_data())
    rgb = np.stack([(pixels >> s) & 0xFF for s in (16, 8, 0)], axis=-1)[:, :width]
    light = (rgb > 200).all(axis=-1)
    assert light[:, :60].sum() > 50, "no y axis numbers"
    assert light[-80:, :].sum() > 100, "no x axis numbers or scale bar"
    saturated = rgb.max(axis=-1).astype(int) - rgb.min(axis=-1) > 80
    assert len(np.unique(rgb[:, -150:][saturated[:, -150:]], axis=0)) > 30, "no colour bar"
