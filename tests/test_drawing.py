"""`multipole draw`: the sketch points of the elements are sampled from the run (checked against the
four-bar's circle intersection), figures and an animation are written, bad options are refused."""
import numpy as np
import pytest

import multipole as mp
from multipole.cli import main
from multipole.drawing import sample

SCENE = "diagrams/linkages/fourbar_crank_rocker.yaml"


def test_sketch_points_are_the_mechanism_positions():
    """The drawn joint P of the four-bar is the circle intersection of coupler (0.6 m about the crank
    tip) and rocker (0.5 m about (0.7, 0)), left of the line from the crank tip to the rocker pivot."""
    result, drawn = sample(mp.load(SCENE), t_end=1.0)
    rocker = [d for d in drawn if d.owner == "rocker"]
    P = rocker[0].xy[:, 1, :]                 # link 1 of the dyad: from the crank tip A to P
    phi = 0.3 + 2.0 * result.t
    A = 0.2 * np.column_stack([np.cos(phi), np.sin(phi)])
    d = np.array([0.7, 0.0]) - A
    dist = np.hypot(d[:, 0], d[:, 1])
    along = (0.6 ** 2 - 0.5 ** 2 + dist ** 2) / (2 * dist)
    across = np.sqrt(0.6 ** 2 - along ** 2)
    u = d / dist[:, None]
    expected = A + along[:, None] * u + across[:, None] * np.column_stack([-u[:, 1], u[:, 0]])
    assert np.abs(P - expected).max() < 1e-10
    assert np.abs(rocker[1].xy[:, 0, :] - [0.7, 0.0]).max() == 0.0      # the frame pivot does not move


def test_draw_writes_the_figures_and_the_animation(tmp_path, capsys):
    out, tf, gif = tmp_path / "m.png", tmp_path / "t.png", tmp_path / "a.gif"
    code = main(["draw", SCENE, "-o", str(out), "--at", "0,0.5,1", "--t-end", "1", "--transfer",
                 "crank.phi:rocker.phi2", "--transfer-plot", str(tf), "--gif", str(gif)])
    assert code == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and tf.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert gif.read_bytes()[:6] in (b"GIF89a", b"GIF87a")


@pytest.mark.parametrize("argv, code", [
    (["--at", "5"], "bad_option"),                       # after the end of the run
    (["--at", "x"], "bad_option"),
    (["--transfer", "crank.phi"], "bad_option"),         # no DRIVE:OUTPUT pair
])
def test_bad_options_are_refused(tmp_path, capsys, argv, code):
    rc = main(["draw", SCENE, "-o", str(tmp_path / "m.png"), "--t-end", "1", "--transfer-plot",
               str(tmp_path / "t.png")] + argv)
    assert rc == 2
    assert f"error[{code}]" in capsys.readouterr().err


def test_a_scene_without_drawings_is_refused(tmp_path, capsys):
    rc = main(["draw", "diagrams/drive_train.yaml", "-o", str(tmp_path / "m.png")])
    assert rc == 2 and "error[no_sketch]" in capsys.readouterr().err
