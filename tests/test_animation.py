"""Animations: a tiny GIF from the command line (frames, size), and clear errors."""

from pathlib import Path

import pytest
from PIL import Image

import jaxclear as jc
from jaxclear.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_animate_writes_a_tiny_gif(tmp_path, capsys):
    gif = tmp_path / "pendulum.gif"
    code = main(["animate", str(ROOT / "examples" / "pendulum.toml"), "--t-end", "0.01", "--n-out", "11",
                 "--frames", "3", "--fps", "5", "--no-progress", "--to", str(gif)])
    assert code == 0, capsys.readouterr().err
    with Image.open(gif) as im:
        assert im.format == "GIF" and im.n_frames == 3
        assert im.size[0] > 500 and im.size[1] > 300


def test_animate_rejects_other_formats(tmp_path):
    with pytest.raises(jc.ParameterError, match=r"\.gif or \.mp4"):
        jc.animate(jc.preset("four-bar"), None, tmp_path / "a.avi")
