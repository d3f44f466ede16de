"""``printapp sweep``: variants, the same table for any number of workers, a given scheduler, resuming."""

from __future__ import annotations

import csv
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from printapp.errors import PrintappError

DESIGN = """
name = "sweep probe"
[base]
width_mm = 4.0
depth_mm = 4.0
thickness_mm = 1.0
[texture]
feature_size_mm = 1.0
[appearance]
gloss_60 = { max = 50 }
[brdf]
rays = 2000
theta_bins = 18
phi_bins = 36
"""
VARY = ["relief.amplitude_um=100:200:3", "relief.grey_levels=false,true"]


def test_vary_specs_and_variants():
    from printapp.design import design_from_dict
    from printapp.sweep import design_raw, parse_vary, variant_values, with_values

    amplitude = parse_vary("relief.amplitude_um=100:400:4")
    assert amplitude.values == (100, 200, 300, 400) and amplitude.numeric
    assert parse_vary("texture.stretch=1:2:3").values == (1.0, 1.5, 2.0)
    assert parse_vary("texture.kind=scn,fbm").values == ("scn", "fbm")
    assert parse_vary("relief.grey_levels=false,true").values == (False, True)
    grid = variant_values([amplitude, parse_vary("texture.kind=scn,fbm")])
    assert len(grid) == 8 and grid[1] == {"relief.amplitude_um": 100, "texture.kind": "fbm"}
    lhs = variant_values([amplitude, parse_vary("texture.stretch=1:8:2")], lhs=5, seed=4)
    assert lhs == variant_values([amplitude, parse_vary("texture.stretch=1:8:2")], lhs=5, seed=4)
    assert len({(p["relief.amplitude_um"] - 100) // 60 for p in lhs}) == 5  # one point per stratum
    for bad in (
        "amplitude=1:2:3",
        "relief.amplitude_um",
        "relief.amplitude_um=1:x:3",
        "relief.amplitude_um=1:2:0",
    ):
        with pytest.raises(PrintappError, match="--vary"):
            parse_vary(bad)
    raw = design_raw(design_from_dict({"relief": {"amplitude_um": 300}}))
    assert with_values(raw, {"relief.amplitude_um": 120}, "d").relief.amplitude_mm == pytest.approx(0.12)
    with pytest.raises(
        PrintappError, match=r"relief.amplitude_um: expected a value in .*\(from --vary relief.amplitude_um\)"
    ):
        with_values(raw, {"relief.amplitude_um": -5}, "d")


@pytest.mark.slow  # worker processes of a Dask cluster
def test_six_points_give_the_same_table_on_one_and_two_workers_of_a_given_scheduler(tmp_path):
    """One cluster started here (as a user's would be), its address given to the sweep: first with
    one worker, then scaled to two; the tables are the same bytes. (The kill test below runs the
    default LocalCluster.)"""
    import tomllib

    from distributed import Client, LocalCluster

    from printapp.design import design_from_dict
    from printapp.sweep import parse_vary, run_sweep

    design = design_from_dict(tomllib.loads(DESIGN))
    varies = [parse_vary(v) for v in VARY]
    with (
        LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster,
        Client(cluster) as client,
    ):
        address = cluster.scheduler_address
        one = run_sweep(design, varies, tmp_path / "one", until="brdf", scheduler=address)
        cluster.scale(2)
        client.wait_for_workers(2, timeout=120)
        two = run_sweep(design, varies, tmp_path / "two", until="brdf", scheduler=address)
    assert one.where == two.where == f"the Dask scheduler at {address}"
    assert one.computed == two.computed == 6
    assert len({row["worker"] for row in one.timings}) == 1
    assert len({row["worker"] for row in two.timings}) == 2  # both workers took points
    for name in ("results.csv", "results.parquet"):
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "two" / name).read_bytes(), name
    rows = list(csv.DictReader((tmp_path / "one" / "results.csv").open()))
    assert [int(r["index"]) for r in rows] == list(range(6))
    assert {"gloss_60", "surrogate_gloss_60", "verdict", "design_hash"} <= set(rows[0])
    assert not any("seconds" in key for key in rows[0])  # timings live in timings.csv
    # grey levels fill the terraces in: never glossier than the same relief without them
    for plain, grey in zip(rows[0::2], rows[1::2], strict=True):
        assert float(grey["gloss_60"]) < float(plain["gloss_60"])
    charts = sorted(p.name for p in (tmp_path / "one").glob("chart_*.png"))
    assert charts == ["chart_relief_amplitude_um.png", "chart_relief_grey_levels.png"]


@pytest.mark.slow  # worker processes of a Dask cluster
def test_a_killed_sweep_resumes_without_recomputing_finished_points(tmp_path):
    design = tmp_path / "probe.toml"
    design.write_text(DESIGN.replace("rays = 2000", "rays = 30000"))
    out = tmp_path / "out"
    exe = str(Path(sys.executable).with_name("printapp"))
    args = [
        exe,
        "sweep",
        str(design),
        "--vary",
        VARY[0],
        "--vary",
        VARY[1],
        "--until",
        "brdf",
        "-o",
        str(out),
    ]
    first = subprocess.Popen(
        [*args, "--workers", "1", "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and len(list((out / "cache").glob("*.json"))) < 2:
        if first.poll() is not None:
            break
        time.sleep(0.05)
    first.send_signal(signal.SIGTERM)
    _, err = first.communicate(timeout=120)
    finished = len(list((out / "cache").glob("*.json")))
    assert first.returncode == 143, err.decode()
    assert 2 <= finished < 6, finished  # stopped part way
    assert not (out / "results.csv").exists()
    again = subprocess.run([*args, "--workers", "0", "--quiet"], capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert f"{finished} from the cache, {6 - finished} computed" in again.stdout
    timings = list(csv.DictReader((out / "timings.csv").open()))
    assert sum(row["cached"] == "True" for row in timings) == finished
