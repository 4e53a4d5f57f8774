"""The command line: default run, flags, configuration files, outputs, and bad input.

Runs ``jaxdobby.cli.main`` in-process (sharing compiled code between tests) and once through the
installed console script.
"""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxdobby.cli import main

SUMMARY_KEYS = {"speed_rpm", "warp_force_n", "thickness_mm", "n_modes", "stroke_mm",
                "deviation_min_mm", "deviation_max_mm", "deviation_pp_mm",
                "link_point_deviation_x_mm", "link_point_deviation_y_mm",
                "velocity_deviation_amp_m_s", "acceleration_amp_m_s2",
                "acceleration_rigid_amp_m_s2", "natural_frequencies_hz", "converged"}
CSV_COLUMNS = {"t_s", "heald_rigid_mm", "heald_flexible_mm", "deviation_mm", "velocity_rigid_m_s",
               "velocity_flexible_m_s", "acceleration_rigid_m_s2", "acceleration_flexible_m_s2"}


def run_cli(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def default_outputs(tmp_path_factory):
    out = tmp_path_factory.mktemp("default")
    code = main(["simulate", "--out", str(out), "--json"])
    return code, out


def test_default_run_writes_everything(default_outputs):
    code, out = default_outputs
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["converged"] is True and summary["n_modes"] == 4
    np.testing.assert_allclose(summary["stroke_mm"], 140.07, atol=0.05)  # DESIGN §6: 140.2 ± 0.5
    # deviation_pp is max - min, consistent within the summary and with the CSV
    np.testing.assert_allclose(summary["deviation_pp_mm"],
                               summary["deviation_max_mm"] - summary["deviation_min_mm"],
                               rtol=1e-12)
    with open(out / "timeseries.csv") as f:
        rows = list(csv.DictReader(f))
    assert CSV_COLUMNS <= set(rows[0])
    dev = np.array([float(r["deviation_mm"]) for r in rows])
    flex = np.array([float(r["heald_flexible_mm"]) - float(r["heald_rigid_mm"]) for r in rows])
    np.testing.assert_allclose(dev, flex, atol=1e-9)  # 15 significant digits in the CSV
    # the summary's extremes: the CSV's extreme samples refined by the parabola through them and
    # their neighbours (np.polyfit here, an independent fit; the cycle is periodic, the last
    # row repeats the first)
    y, t = dev[:-1], np.array([float(r["t_s"]) for r in rows])[:-1]

    def vertex(i, sign):
        idx = [(i - 1) % len(y), i, (i + 1) % len(y)]
        tt = t[i] + (np.arange(3) - 1) * (t[1] - t[0])
        a, b, c = np.polyfit(tt - t[i], y[idx], 2)
        assert sign * a < 0
        return c - b**2 / (4 * a)

    refined = vertex(int(np.argmax(y)), 1) - vertex(int(np.argmin(y)), -1)
    np.testing.assert_allclose(refined, summary["deviation_pp_mm"], rtol=1e-8)
    assert dev.max() - dev.min() <= summary["deviation_pp_mm"] <= 1.001 * (dev.max() - dev.min())
    for name in ("deviation", "velocity", "acceleration", "link_point_deviation", "displacement"):
        assert (out / f"{name}.png").stat().st_size > 10_000
    # the arm's stress: the CSV's critical-point column reaches the summary's peak |σ|
    critical = np.array([float(r["stress_critical_mpa"]) for r in rows])
    np.testing.assert_allclose(np.abs(critical).max(), summary["stress_max_mpa"], rtol=1e-12)
    np.testing.assert_allclose(critical.max() - critical.min(), summary["stress_range_mpa"],
                               rtol=1e-12)
    assert summary["stress_max_edge"] in ("left", "right") and summary["fatigue_safety_factor"] > 0
    assert (out / "arm_stress.png").stat().st_size > 10_000


def test_json_to_stdout(capsys, default_outputs):
    code, out, err = run_cli(capsys, "simulate", "--json")
    assert code == 0
    summary = json.loads(out)  # stdout is pure JSON; progress went to stderr
    assert SUMMARY_KEYS <= set(summary)
    assert json.loads((default_outputs[1] / "summary.json").read_text())["deviation_pp_mm"] == \
        pytest.approx(summary["deviation_pp_mm"], rel=1e-12)


def test_table_output(capsys, default_outputs):
    code, out, _ = run_cli(capsys, "simulate")
    assert code == 0 and "displacement deviation, peak to peak" in out and "mm" in out


def test_every_flag(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "simulate", "--speed", "900", "--warp-force", "800",
                           "--stroke", "115", "--thickness", "7", "--modes", "3",
                           "--coupling", "one-way", "--warp-law", "opposing", "--json")
    assert code == 0
    s = json.loads(out)
    assert s["speed_rpm"] == pytest.approx(900) and s["warp_force_n"] == pytest.approx(800)
    assert s["stroke_mm"] == pytest.approx(115, abs=1e-6)
    assert s["thickness_mm"] == pytest.approx(7) and s["n_modes"] == 3
    assert s["coupling"] == "one-way" and s["warp_law"] == "opposing"
    assert len(s["natural_frequencies_hz"]) == 3


def test_config_file_and_flags_override(capsys, tmp_path):
    cfg = tmp_path / "machine.toml"
    cfg.write_text('[operating]\nspeed_rpm = 900.0\nwarp_force_n = 800.0\n'
                   '[stroke]\nstroke_mm = 115.0\n[arm]\nthickness_mm = 7.0\n'
                   '[model]\nn_modes = 3\ncoupling = "one-way"\nwarp_law = "opposing"\n')
    code, out, _ = run_cli(capsys, "simulate", "--config", str(cfg), "--json")
    assert code == 0
    from_file = json.loads(out)
    assert from_file["stroke_mm"] == pytest.approx(115, abs=1e-6)
    # same setup as test_every_flag: the same numbers. A flag overrides the file (the warp
    # force: a float of the same program; a new speed would change the RK4 step count of the
    # one-way model and compile another program for the same claim)
    code, out, _ = run_cli(capsys, "simulate", "--config", str(cfg), "--warp-force", "900",
                           "--json")
    overridden = json.loads(out)
    assert overridden["warp_force_n"] == pytest.approx(900)
    assert overridden["speed_rpm"] == pytest.approx(900)


@pytest.mark.parametrize("args, field", [
    (["--speed", "0"], "--speed"),
    (["--speed", "-800"], "--speed"),
    (["--speed", "nan"], "--speed"),
    (["--thickness", "0"], "--thickness"),
    (["--thickness", "-6"], "--thickness"),
    (["--warp-force", "inf"], "--warp-force"),
    (["--stroke", "200"], "reachable range"),
    (["--stroke", "20"], "reachable range"),
    (["--modes", "0"], "--modes"),
    (["--modes", "31"], "--modes"),
    (["--config", "/nonexistent/machine.toml"], "does not exist"),
])
def test_bad_input_is_one_clear_line(capsys, args, field):
    code, out, err = run_cli(capsys, "simulate", *args)
    assert code == 2
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert field in err and ("valid range" in err or "reachable" in err or "exist" in err), err


@pytest.mark.parametrize("text, field", [
    ("[operating\nspeed_rpm = 800", "not valid TOML"),
    ("[operating]\nspeed = 800\n", "unknown key 'speed'"),
    ("[wheel]\nx = 1\n", "unknown table [wheel]"),
    ("[downstream]\nheald_frame_mass_kg = 0.0\n", "heald_frame_mass_kg"),
    ("[downstream]\nheald_frame_mass_kg = -12.0\n", "heald_frame_mass_kg"),
    ("[downstream]\nblade_inertia_kg_m2 = -0.01\n", "blade_inertia_kg_m2"),
    ("[arm]\nthickness_mm = \"six\"\n", "thickness_mm"),
    ("[model]\nn_modes = 40\n", "n_modes"),
    ("[model]\ncoupling = \"three-way\"\n", "coupling"),
    ("[stroke]\nstroke_mm = 115.0\nlink11_position_mm = 150.0\n", "not both"),
])
def test_bad_config_is_one_clear_line(capsys, tmp_path, text, field):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(text)
    code, out, err = run_cli(capsys, "simulate", "--config", str(cfg))
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert field in err, err


def test_unreadable_config(capsys, tmp_path):
    code, _, err = run_cli(capsys, "simulate", "--config", str(tmp_path))  # a directory
    assert code == 2 and "cannot read" in err and "Traceback" not in err


def test_console_script():
    # The installed entry point, as a user runs it: a quick command, and a bad input. The
    # script of this interpreter's installation (another `jaxdobby` may come first on PATH).
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    here = Path(sys.executable).parent / "jaxdobby"
    script = str(here) if here.exists() else "jaxdobby"
    proc = subprocess.run([script, "beam", "--modes", "3"], capture_output=True, text=True,
                          env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "in the mechanism [Hz]" in proc.stdout
    bad = subprocess.run([script, "simulate", "--speed", "-1"], capture_output=True,
                         text=True, env=env, timeout=600)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert bad.stderr.strip().splitlines() == [
        "jaxdobby simulate: error: --speed = -1 r/min is outside the valid range (>= 100 and <= 1800 r/min)"]


def test_ctrl_c_ends_with_one_line_and_status_130(capsys, monkeypatch):
    """An interrupt (Ctrl-C) is not a crash: one line naming the command, no traceback, and
    the status a shell gives a process stopped by SIGINT (128 + 2)."""
    import jaxdobby.cli as cli

    def interrupted(ns):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_beam", interrupted)
    assert main(["beam"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == "jaxdobby beam: interrupted"
