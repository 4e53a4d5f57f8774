"""Pictures: the drawing's geometry against the kinematics, the animation's frames, the
resonance map's frequency band and crossings, and the command-line flags."""

import json
import math

import equinox as eqx
import numpy as np
import pytest
from PIL import Image

from jaxdobby import simulate
from jaxdobby.cli import main
from jaxdobby.dobby import LINK, RING
from jaxdobby.machine import Machine
from jaxdobby.outputs import coupled_frequencies, rigid_outputs
from jaxdobby.pictures.animation import DPI, FIGSIZE, animate, ffmpeg_binary
from jaxdobby.pictures.campbell import (campbell_figure, crossing_speeds, frequency_band,
                                        max_harmonic)
from jaxdobby.pictures.mechanism import draw_pose, mechanism_figure
from jaxdobby.pictures.pose import arm_sampling, crank_angle_at, flexible_pose, rigid_pose
from jaxdobby.plots import plt

ANGLES = np.array([0.0, 90.0, 180.0, 300.0, 360.0, 500.0, 640.0])  # loom angles [deg]
GIF_SIZE = (round(FIGSIZE[0] * DPI), round(FIGSIZE[1] * DPI))


@pytest.fixture(scope="module")
def default_run():
    return simulate()


@pytest.fixture(scope="module")
def sampling(default_run):
    return arm_sampling(default_run.model.machine, default_run.model)


def _length(line):
    (a, b) = line.get_xydata()
    return float(np.linalg.norm(b - a)) * 1e-3  # drawn in mm


@pytest.mark.parametrize("stroke_mm", [140.0, 115.0])
def test_drawn_link_lengths_are_the_configured_ones(stroke_mm, sampling):
    machine = Machine.default()
    s = sampling
    if stroke_mm != 140.0:
        machine = machine.with_stroke(stroke_mm * 1e-3)
        s = arm_sampling(machine)
    chain = machine.chain
    poses = rigid_pose(machine, crank_angle_at(machine, np.radians(ANGLES)), s)
    r_j = float(np.linalg.norm(np.asarray(chain.arm.point(chain.ring_joint_arc_length))))
    r_p = float(np.linalg.norm(np.asarray(chain.arm.point(chain.link11_arc_length))))
    for i in range(ANGLES.size):
        fig, ax = plt.subplots()
        art = draw_pose(ax, poses.at(i), s)
        # Lengths measured on the drawn lines equal the configured links to 1e-9 m (they are
        # float64 differences of ~0.5 m coordinates: round-off is ~1e-16 m).
        for key, value in (("crank", chain.eccentricity), ("ring_link", chain.ring_link_length),
                           ("link11", chain.link11_length), ("blade_input", chain.blade_input_arm),
                           ("blade_output", chain.blade_output_arm),
                           ("tumbler", chain.tumbler_length)):
            assert abs(_length(art[key]) - float(value)) < 1e-9, key
        ring, link = art["ring_link"].get_xydata()[1], art["link11"].get_xydata()[0]
        assert abs(np.linalg.norm(ring) * 1e-3 - r_j) < 1e-9  # ring joint on the arm's circle
        assert abs(np.linalg.norm(link) * 1e-3 - r_p) < 1e-9  # link-11 joint on the arm
        arm = art["arm"].get_xydata()
        assert np.min(np.linalg.norm(arm - ring, axis=1)) < 1e-6  # J is a drawn arm point [mm]
        u, v = (art["blade_input"].get_xydata()[1] - art["blade_input"].get_xydata()[0],
                art["blade_output"].get_xydata()[1] - art["blade_output"].get_xydata()[0])
        angle = math.atan2(u[0] * v[1] - u[1] * v[0], u @ v)
        assert abs(angle - float(chain.blade_output_offset)) < 1e-12  # the bell crank's angle
        assert abs(art["tumbler"].get_xydata()[1][0] * 1e-3 - float(chain.frame_guide_x)) < 1e-12
        plt.close(fig)
    # bottom at loom angle 0, top at 360: the drawn heald frame travels the machine's stroke
    travel = poses.heald_frame[4, 1] - poses.heald_frame[0, 1]
    assert abs(travel - float(machine.stroke())) < 1e-9


def test_pose_follows_the_rigid_motion_of_the_model(default_run, sampling):
    model = default_run.model
    t = np.radians(ANGLES) / float(model.operating.speed)
    poses = rigid_pose(model.machine, crank_angle_at(model.machine, np.radians(ANGLES)), sampling)
    expected = np.asarray(eqx.filter_jit(rigid_outputs)(model, t)["heald_rigid"])
    np.testing.assert_allclose(poses.heald_frame[:, 1], expected, rtol=0, atol=1e-12)


def test_deformed_pose_reproduces_the_coupled_run(default_run, sampling):
    """q of the run through the arm's mode shapes moves the link-11 joint and the heald frame
    exactly as the coupled model did (its own rows, independent of the drawing's)."""
    run, model = default_run, default_run.model
    rows = np.asarray(model.body.points)
    # the link rows fix the modes' signs; the ring-joint rows are then an independent check
    np.testing.assert_allclose(sampling.ring_rows, rows[RING], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(sampling.link_rows, rows[LINK], rtol=1e-9, atol=1e-12)
    idx = np.array([0, 200, 431, 700, 1100, 1500])
    t = np.asarray(run.series.t)[idx]
    crank = crank_angle_at(model.machine, float(model.operating.speed) * t)
    q = np.asarray(run.series.modal)[idx]
    rigid = rigid_pose(model.machine, crank, sampling)
    bent = flexible_pose(model.machine, crank, sampling, q)
    # differences of ~0.2 m positions: round-off ~1e-16 m; the deviations are ~1e-3 m
    np.testing.assert_allclose(bent.link11_joint - rigid.link11_joint,
                               np.asarray(run.series.link_point_deviation)[idx], atol=1e-12)
    np.testing.assert_allclose(bent.heald_frame[:, 1], np.asarray(run.series.heald_flexible)[idx],
                               atol=1e-12)


def test_mechanism_figure_labels_every_part(default_run, sampling):
    fig = mechanism_figure(Machine.default(), 180.0, sampling=sampling)
    ax = fig.axes[0]
    numbers = {t.get_text() for t in ax.texts}
    assert {"8", "9", "10", "11", "12", "13", "16"} <= numbers
    assert ax.get_xlabel().startswith("x [mm]") and ax.get_ylabel() == "y [mm]"
    assert ax.get_aspect() == 1.0  # to scale
    plt.close(fig)
    # with modal coordinates: the deformed arm (red) over the rigid one; its tip is displaced by
    # the magnified deformation of the arm's rows at the tip
    q = np.asarray(default_run.series.modal)[300]
    fig = mechanism_figure(Machine.default(), 180.0, sampling=sampling, q=q, magnification=20.0)
    red = [line for line in fig.axes[0].lines if line.get_color() == "C3"]
    assert len(red) == 1
    rigid = rigid_pose(Machine.default(), crank_angle_at(Machine.default(), np.radians(180.0)),
                       sampling)
    shift = np.linalg.norm(red[0].get_xydata()[-1] * 1e-3 - rigid.arm[-1])
    np.testing.assert_allclose(shift, 20.0 * np.linalg.norm(sampling.modal_rows[-1] @ q),
                               rtol=1e-9)  # a rotation keeps the length of the displacement
    plt.close(fig)


def test_animation_gif_frames_and_size(default_run, tmp_path):
    n = 5
    path = animate(default_run, tmp_path / "cycle.gif", n_frames=n, magnification=20.0)
    with Image.open(path) as im:
        assert im.n_frames == n and im.size == GIF_SIZE
    # deterministic: the same run and arguments give the same file, byte for byte
    again = animate(default_run, tmp_path / "again.gif", n_frames=n, magnification=20.0)
    assert again.read_bytes() == path.read_bytes()
    # the colour hook: one value per element and frame; a wrong shape is refused
    values = np.linspace(0.0, 1.0, n * 10).reshape(n, 10)
    path = animate(default_run, tmp_path / "stress.gif", n_frames=n, element_values=values,
                   colour_label="stress [MPa]")
    with Image.open(path) as im:
        assert im.n_frames == n and im.size == GIF_SIZE
    with pytest.raises(ValueError, match="element_values has shape"):
        animate(default_run, tmp_path / "bad.gif", n_frames=n, element_values=values[:, :3])


def test_animation_follows_a_lift_plan(default_run, tmp_path):
    """``jaxdobby loom --animate``'s drawing over a plan's repeat, cheaply: the default run's
    model with the plan "1100" (build_model only stores the plan) and an undeformed arm. The
    crank follows the plan, not plain weave: at x = P·t/T = 1.6 (pick 2, which does not move)
    the drawn frame is at the top, at x = 0 and 3.2 (pick 4's dwell, its last pick's) at the
    bottom — heights equal to the rigid mechanism's at its dead centres, ψ = 2π and 0 of
    plain weave, to round-off (the same closed-form loop closures at the same crank angles);
    moving (x = 0.8 rising, 2.4 falling) strictly between; the loom-angle axis spans the
    repeat, 4·360°; the GIF has one image per requested frame."""
    import dataclasses
    from types import SimpleNamespace

    import jax.numpy as jnp

    from jaxdobby.pictures.animation import animation_frames
    from jaxdobby.weave.command import FRAMES_PER_PICK, animation_images

    model = dataclasses.replace(default_run.model, lift_plan=jnp.array([1.0, 1.0, 0.0, 0.0]))
    n_t = 4 * 864 + 1
    t = np.linspace(0.0, float(model.period), n_t)
    run = SimpleNamespace(model=model, series=SimpleNamespace(
        t=t, modal=np.zeros((n_t, model.n_modes)), deviation=np.zeros(n_t)))
    n = 5
    psi, rigid, _, _, _, sampling = animation_frames(run, n, magnification=1.0)
    np.testing.assert_allclose(psi, 4 * 360.0 * np.arange(n) / n, rtol=1e-12)
    y = np.asarray(rigid.heald_frame)[:, 1]
    machine = model.machine
    bottom, top = np.asarray(rigid_pose(machine, crank_angle_at(machine, np.array(
        [0.0, 2.0 * math.pi])), sampling).heald_frame)[:, 1]
    np.testing.assert_allclose(y[[0, 2, 4]], [bottom, top, bottom], rtol=0, atol=1e-12)
    assert bottom + 1e-3 < y[3] < top - 1e-3  # τ = 0.36 of pick 3's index: mid-fall
    assert top - 1e-4 < y[1] < top - 1e-6  # τ = 0.92 of pick 1's index: the rise ending
    path = animate(run, tmp_path / "plan.gif", n_frames=n, magnification=1.0)
    with Image.open(path) as im:
        assert im.n_frames == n and im.size == GIF_SIZE
    assert animation_images(4) == 4 * FRAMES_PER_PICK and animation_images(100) == 360


@pytest.mark.skipif(ffmpeg_binary() is None, reason="no ffmpeg binary (optional extra: video)")
def test_animation_mp4_frames_and_size(default_run, tmp_path):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")  # its reader decodes the file
    path = animate(default_run, tmp_path / "cycle.mp4", n_frames=4, magnification=20.0)
    frames = imageio_ffmpeg.read_frames(str(path))
    meta = next(frames)
    assert tuple(meta["size"]) == GIF_SIZE and sum(1 for _ in frames) == 4


def test_simulate_writes_drawing_and_animation(default_run, tmp_path, capsys):
    code = main(["simulate", "--out", str(tmp_path), "--animate", "--frames", "6", "--json"])
    assert code == 0
    assert json.loads(capsys.readouterr().out)["converged"] is True
    assert (tmp_path / "mechanism.png").stat().st_size > 20_000
    with Image.open(tmp_path / "animation.gif") as im:
        assert im.n_frames == 6 and im.size == GIF_SIZE


@pytest.mark.parametrize("args, text", [
    (["simulate", "--animate", "cycle.avi"], "--animate cycle.avi: the file must end in"),
    (["simulate", "--frames", "1"], "--frames = 1 is outside"),
    (["simulate", "--loom-angle", "800"], "--loom-angle = 800 is outside"),
    (["simulate", "--magnification", "-2"], "--magnification = -2 is outside"),
    (["campbell", "--phases", "2"], "--phases = 2 is outside"),
    (["campbell", "--values", "0"], "speed = 0 r/min is outside"),
])
def test_picture_flags_bad_input(args, text, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert text in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_frequency_band_over_the_cycle(default_run):
    model = default_run.model
    band = frequency_band(model, n_phases=24)
    # its mid-stroke value is coupled_frequencies' (same linearisation; vmapped vs not: 1e-10)
    np.testing.assert_allclose(band.mid_stroke, np.asarray(coupled_frequencies(model)),
                               rtol=1e-10)
    assert np.all(band.low <= band.mid_stroke) and np.all(band.mid_stroke <= band.high)
    # the bottom dwell (loom angle within ±50° of 0/720) holds the mechanism still: equal there
    dwell = (band.loom_angle[:-1] < 45.0) | (band.loom_angle[:-1] > 675.0)
    f = band.frequencies[:-1][dwell]
    assert dwell.sum() == 3  # 0°, 30° and 690° on the 30° grid
    np.testing.assert_allclose(f, np.broadcast_to(f[0], f.shape), rtol=1e-10)
    # the frame-on-arm mode moves with the configuration: a band, not a line (README: 107 Hz
    # at mid-stroke)
    assert 100.0 < band.low[0] < band.mid_stroke[0] < band.high[0] < 125.0


def test_crossing_speeds_closed_form():
    # band 100…110 Hz, speeds 400…1200 r/min: k·n/60 in the band for n in [6000/k, 6600/k]
    got = crossing_speeds(100.0, 110.0, (400.0, 1200.0), 20)
    assert [k for k, _, _ in got] == list(range(5, 17))
    assert got[0] == pytest.approx((5, 1200.0, 1200.0))
    assert got[1] == pytest.approx((6, 1000.0, 1100.0))
    assert got[-1] == pytest.approx((16, 400.0, 412.5))
    assert max_harmonic(110.0, 400.0) == 17


def test_campbell_figure_axes_and_rays(tmp_path):
    from jaxdobby.pictures.campbell import FrequencyBand

    f = np.array([[104.0, 4000.0], [110.0, 4200.0], [117.0, 3800.0]])
    band = FrequencyBand(np.array([0.0, 360.0, 180.0]), f, f[-1])
    speeds = np.arange(400.0, 1201.0, 100.0)
    fig = campbell_figure(band, speeds, np.linspace(1.0, 9.0, speeds.size))
    ax, ax_dev = fig.axes
    assert ax.get_ylabel() == "frequency [Hz]" and ax_dev.get_xlabel() == "loom speed [r/min]"
    rays = [line for line in ax.lines if line.get_label().startswith("k = ")]
    assert len(rays) == max_harmonic(1.5 * 117.0, 400.0)  # rays up to the axis top at 400 r/min
    k = 8  # ray k = 8 at 800 r/min is at 8·800/60 = 106.7 Hz
    x, y = rays[k - 1].get_data()
    assert np.interp(800.0, x, y) == pytest.approx(k * 800.0 / 60.0)
    fig.savefig(tmp_path / "campbell.png")
    assert (tmp_path / "campbell.png").stat().st_size > 10_000
    plt.close(fig)


@pytest.mark.slow
def test_campbell_command(tmp_path, capsys):
    code = main(["campbell", "--values", "700", "800", "--phases", "8", "--out", str(tmp_path),
                 "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["speeds_rpm"] == [700.0, 800.0] and len(out["deviation_pp_mm"]) == 2
    assert any(c["harmonic"] == 8 for c in out["crossings"])
    assert (tmp_path / "campbell.png").stat().st_size > 10_000
    assert (tmp_path / "campbell.csv").read_text().count("\n") == 3
