"""First contact: ``renderlab scenes``, ``info``, ``show``, ``--dry-run``, "did you mean" and defaults in ``--help``.

Tiny real outputs (a 24x18 truth set, a 2-run 64x48 campaign and its published folder) are made once per module;
every bad input below must give exit code 2, exactly one line ``renderlab: error: ...`` on stderr, no traceback,
and leave no folder (nor hidden staging folder) behind.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from renderlab.builtin import SCENES_DIR
from renderlab.cli import main
from renderlab.scenario import load_scenario, read_toml, scenario_from_dict

SCENE = SCENES_DIR / "analytic_sphere_box.toml"
EV5 = SCENES_DIR / "ev5_descent.toml"
TINY_TS = ["camera.width=24", "camera.height=18", "camera.fx=26", "camera.fy=25", "camera.cx=11.5", "camera.cy=8.5",
           "trajectory.frames=2", "render.spp=2"]
TINY_CAMP = ["camera.width=64", "camera.height=48", "camera.fx=66", "camera.fy=65", "camera.cx=32", "camera.cy=23",
             "render.spp=4", "trajectory.frames=1", "perturbations.position_sigma_m=[0.1,0.1,0.1]"]
PREFIX = "renderlab: error: "


def sets(kvs: list[str]) -> list[str]:
    return [a for kv in kvs for a in ("--set", kv)]


def run(capsys, argv: list[str]) -> tuple[int, str, str]:
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """A tiny truth set, a 2-run campaign and its published study folder (with report/summary.csv)."""
    d = tmp_path_factory.mktemp("discovery")
    ts, camp, pub = d / "ts", d / "camp", d / "results" / "study"
    assert main(["render", str(SCENE), "--out", str(ts), "--quiet", *sets(TINY_TS)]) == 0
    assert main(["campaign", str(SCENE), "--runs", "2", "--out", str(camp), "--workers", "0", "--quiet",
                 "--seed", "3", *sets(TINY_CAMP)]) == 0
    assert main(["publish", str(camp), "--out", str(pub)]) == 0
    return {"ts": ts, "camp": camp, "pub": pub}


# ----------------------------------------------------------------------------------------- scenes
def test_scenes_lists_every_builtin_scenario_with_its_world(capsys):
    rc, out, _ = run(capsys, ["scenes"])
    assert rc == 0
    files = sorted(SCENES_DIR.glob("*.toml"))
    assert files
    rows = {line.split()[0]: line.split() for line in out.splitlines() if line.split()}
    for f in files:
        world = read_toml(f)["world"].get("kind", "analytic")
        assert rows[f.stem][1] == world, f.stem
        assert read_toml(f).get("description", "—")[:20] in out
    assert "retina_vs_spc*" in " ".join(rows["ev5_descent"][4:]) and "STUDY" in rows   # ev5 has several studies


# ----------------------------------------------------------------------------------------- info
def test_info_truth_set(capsys, made):
    rc, out, _ = run(capsys, ["info", made["ts"]])
    assert rc == 0
    assert out.startswith(f"truth set {made['ts']}")
    for needle in ("frames        2", "24 × 18 px", "mitsuba", "llvm_ad_mono", "seed          7", "size on disk"):
        assert needle in out, needle


def test_info_campaign(capsys, made):
    rc, out, _ = run(capsys, ["info", made["camp"]])
    assert rc == 0 and out.startswith("campaign ")
    for needle in ("study         analytic_pointing", "2 planned: 2 finished, 0 failed", "SeedSequence(3,",
                   "measurements (", "rows)"):
        assert needle in out, needle


def test_info_published_study_with_headline_rows(capsys, made):
    assert (made["pub"] / "report" / "summary.csv").is_file()
    rc, out, _ = run(capsys, ["info", made["pub"]])
    assert rc == 0 and out.startswith("published study folder ")
    assert "2 finished" in out and "headline rows of" in out and "measurements" in out


# ----------------------------------------------------------------------------------------- show
@pytest.mark.parametrize("name", sorted(p.stem for p in SCENES_DIR.glob("*.toml")))
def test_show_round_trips_every_builtin_scenario(capsys, name):
    overrides = ["camera.width=128", "render.spp=3"] if name == "analytic_sphere_box" else []
    rc, out, _ = run(capsys, ["show", name, *sets(overrides)])
    assert rc == 0
    shown = scenario_from_dict(tomllib.loads(out), "show output")
    expected, _ = load_scenario(SCENES_DIR / f"{name}.toml", overrides)
    assert shown.to_dict() == expected.to_dict()
    rc, bare, _ = run(capsys, ["show", str(SCENES_DIR / f"{name}.toml"), "--no-defaults", *sets(overrides)])
    assert rc == 0 and scenario_from_dict(tomllib.loads(bare)).to_dict() == expected.to_dict()


def test_show_marks_defaults_and_resolves_fov(capsys, tmp_path):
    rc, _, err = run(capsys, ["show", "analytic_sphere_box", "--set", "camera.fov_deg=90"])
    assert rc == 2 and "camera.fov_deg and camera.fx are both given" in err  # the file gives fx
    text = "".join(line for line in SCENE.read_text().splitlines(keepends=True) if not line.startswith(("fx", "fy")))
    (tmp_path / "fov.toml").write_text(text)
    rc, out, _ = run(capsys, ["show", tmp_path / "fov.toml", "--set", "camera.fov_deg=90"])
    body = out.split("\n\n", 1)[1]
    assert rc == 0 and "fov_deg" not in body and "fx = 128.0" in body and "fy = 128.0" in body
    assert "# skew = 0.0" in body and "# [perturbations]" in body and out.startswith("# renderlab show ")


# ----------------------------------------------------------------------------------------- dry run
def test_render_dry_run_prints_and_creates_nothing(capsys, tmp_path):
    out_dir = tmp_path / "never"
    rc, out, _ = run(capsys, ["render", EV5, "--out", out_dir, "--dry-run"])
    assert rc == 0 and "nothing is created" in out
    for needle in ("frames          12", "1024 × 1024 px", "rays", "EV5 facets", "site cells", "per frame",
                   "cost limits     within"):
        assert needle in out, needle
    rc, out, _ = run(capsys, ["render", SCENE, "--out", out_dir, "--dry-run", "--set", "render.spp=65536",
                              "--set", "camera.width=8192", "--set", "camera.height=8192"])
    assert rc == 0 and "over:" in out and "--allow-large" in out
    assert list(tmp_path.iterdir()) == []


def test_campaign_dry_run_prints_and_creates_nothing(capsys, tmp_path, made):
    out_dir = tmp_path / "never"
    rc, out, _ = run(capsys, ["campaign", SCENE, "--runs", "5", "--out", out_dir, "--dry-run", *sets(TINY_CAMP)])
    assert rc == 0 and "study           analytic_pointing" in out and "× 5 runs" in out
    assert list(tmp_path.iterdir()) == []
    rc, out, _ = run(capsys, ["campaign", SCENE, "--runs", "2", "--out", made["camp"], "--dry-run", "--resume",
                              "--seed", "3", "--workers", "0", *sets(TINY_CAMP)])
    assert rc == 0 and "2 already finished" in out


# ----------------------------------------------------------------------------------------- did you mean, --help
def test_did_you_mean_for_a_scenario_key(capsys, tmp_path):
    rc, _, err = run(capsys, ["render", SCENE, "--out", tmp_path / "x", "--set", "camera.widht=3"])
    assert rc == 2 and "unknown key 'camera.widht'; did you mean 'width'?" in err
    assert not (tmp_path / "x").exists()


def test_did_you_mean_for_a_command():
    proc = subprocess.run([sys.executable, "-m", "renderlab", "rendr"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()] and "did you mean 'render'?" in proc.stderr


@pytest.mark.parametrize("command", ["render", "visibility", "measure", "campaign", "crosscheck", "report", "demo",
                                     "scenes", "show", "info"])
def test_help_shows_defaults(capsys, command):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    out = capsys.readouterr().out
    assert "(default: None)" not in out and "(default: False)" not in out and "(default: [])" not in out
    if command in ("visibility", "measure", "campaign", "demo"):
        assert "default" in out
    if command == "visibility":
        assert "--hours H             length of each orbit track, hours (default: 24.0)" in out


# ----------------------------------------------------------------------------------------- bad input
def _files(tmp: Path) -> None:
    (tmp / "empty").mkdir()
    (tmp / "full").mkdir()
    (tmp / "full" / "keep.txt").write_text("x")
    (tmp / "bad_ts").mkdir()
    (tmp / "bad_ts" / "manifest.json").write_text('{"format": "something/9", "frames": []}')
    (tmp / "bad_camp").mkdir()
    (tmp / "bad_camp" / "campaign.json").write_text("{not json")
    (tmp / "s.toml").write_text(SCENE.read_text())


OUT = "OUT"  # placeholder for the output folder that must not be created
BAD = {
    "command_typo": (["rendr"], "did you mean 'render'"),
    "command_typo_scenes": (["scene"], "did you mean 'scenes'"),
    "command_typo_show": (["shwo", "x"], "did you mean 'show'"),
    "command_typo_info": (["inof", "x"], "did you mean 'info'"),
    "show_unknown_scenario": (["show", "no_such_scenario"], "not found"),
    "show_scenario_typo": (["show", "ev5_desent"], "did you mean 'ev5_descent'"),
    "show_key_typo": (["show", "analytic_sphere_box", "--set", "camera.widht=3"], "did you mean 'width'"),
    "show_key_typo_render": (["show", "analytic_sphere_box", "--set", "render.sp=3"], "did you mean 'spp'"),
    "show_key_typo_site": (["show", "ev5_descent", "--set", "world.site.cel_m=0.1"], "did you mean 'cell_m'"),
    "show_key_typo_body": (["show", "analytic_sphere_box", "--set", "world.bodies.0.radus_m=1"],
                           "did you mean 'radius_m'"),
    "show_key_typo_study": (["show", "coastline_ekf", "--set", "coastline.mod=image"], "did you mean 'mode'"),
    "show_bad_value": (["show", "analytic_sphere_box", "--set", "camera.width=0"], "camera.width"),
    "show_set_without_equals": (["show", "analytic_sphere_box", "--set", "camera"], "--set expects KEY=VALUE"),
    "show_trajectory_misfit": (["show", "analytic_sphere_box", "--set", "trajectory.kind=leo"],
                               "unknown key 'trajectory.target_m'"),
    "show_unknown_world": (["show", "analytic_sphere_box", "--set", "world.kind=moon"], "kind must be one of"),
    "show_fov_out_of_range": (["show", "analytic_sphere_box", "--set", "camera.fov_deg=200"], "fov_deg"),
    "show_empty_path": (["show", ""], "must not be empty"),
    "show_folder": (["show", "{tmp}/empty"], "is a folder"),
    "show_unknown_renderer": (["show", "analytic_sphere_box", "--set", "render.renderer=blender"],
                              "render.renderer"),
    "info_missing": (["info", "{tmp}/nowhere"], "not found"),
    "info_scenario_file": (["info", "{tmp}/s.toml"], "renderlab show"),
    "info_empty_folder": (["info", "{tmp}/empty"], "not a truth set, campaign or published study folder"),
    "info_bad_manifest": (["info", "{tmp}/bad_ts"], "format"),
    "info_bad_campaign": (["info", "{tmp}/bad_camp"], "cannot read"),
    "info_no_path": (["info"], "required: PATH"),
    "scenes_unknown_option": (["scenes", "--bogus"], "unrecognized arguments: --bogus"),
    "render_dry_key_typo": (["render", SCENE, "--out", OUT, "--dry-run", "--set", "trajectory.rnge_m=3"],
                            "did you mean 'range_m'"),
    "render_dry_frames_zero": (["render", SCENE, "--out", OUT, "--dry-run", "--frames", "0"], "--frames"),
    "render_dry_renderer_typo": (["render", SCENE, "--out", OUT, "--dry-run", "--renderer", "mitsba"],
                                 "did you mean 'mitsuba'"),
    "render_dry_variant": (["render", SCENE, "--out", OUT, "--dry-run", "--set", "render.variant=optix"],
                           "render.variant"),
    "render_dry_bool_for_number": (["render", SCENE, "--out", OUT, "--dry-run", "--set", "trajectory.frames=true"],
                                   "trajectory.frames"),
    "render_dry_full_out": (["render", SCENE, "--out", "{tmp}/full", "--dry-run"], "not empty"),
    "render_dry_missing_scenario": (["render", "{tmp}/none.toml", "--out", OUT, "--dry-run"], "not found"),
    "campaign_dry_runs_zero": (["campaign", SCENE, "--runs", "0", "--out", OUT, "--dry-run"], "--runs"),
    "campaign_dry_study_misfit": (["campaign", SCENE, "--runs", "2", "--out", OUT, "--dry-run", "--set",
                                   "campaign.study=retina_vs_spc"], "runs on world kind"),
    "campaign_dry_study_typo": (["campaign", SCENE, "--runs", "2", "--out", OUT, "--dry-run", "--set",
                                 "campaign.study=analytic_pointng"], "did you mean 'analytic_pointing'"),
    "campaign_dry_negative_sigma": (["campaign", SCENE, "--runs", "2", "--out", OUT, "--dry-run", "--set",
                                     "perturbations.position_sigma_m=[-1,0,0]"], "perturbations.position_sigma_m"),
    "campaign_dry_workers_and_scheduler": (["campaign", SCENE, "--runs", "2", "--out", OUT, "--dry-run",
                                            "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not allowed"),
    "campaign_dry_ev5_coarse_site": (["campaign", EV5, "--runs", "2", "--out", OUT, "--dry-run", "--set",
                                      "world.site.cell_m=0.1"], "finer than the site"),
    "campaign_dry_full_out": (["campaign", SCENE, "--runs", "2", "--out", "{tmp}/full", "--dry-run"],
                              "holds no campaign"),
    "campaign_dry_timings_typo": (["campaign", SCENE, "--runs", "2", "--out", OUT, "--dry-run", "--timings",
                                   "seperate"], "did you mean 'separate'"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_input_is_one_line_exit_2_nothing_created(name, tmp_path, capsys):
    _files(tmp_path)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    argv, needle = BAD[name]
    argv = [str(tmp_path / "out") if a == OUT else str(a).format(tmp=tmp_path) for a in argv]
    rc, _, err = run(capsys, argv)
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and lines[0].startswith(PREFIX), err
    assert needle in lines[0] and "Traceback" not in err
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # no output, no staging folder
