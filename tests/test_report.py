"""``report.html``: sections, embedded images, no outside references, escaping, the failed gate, a browser."""

import base64
import html
import io
import json
import re
import shutil
import subprocess
from html.parser import HTMLParser

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from printapp.cli import app
from printapp.design_io import load_design
from printapp.report import metric_rows, report_html, sweep_settings

pytestmark = pytest.mark.slow  # end to end: `make test-fast` leaves these out

runner = CliRunner()

NAME = "<script>alert('x')</script> & tile"
SMALL = """
name = "{name}"
[base]
width_mm = 6.0
depth_mm = 6.0
[appearance]
gloss_60 = {gloss}
[brdf]
rays = 5000
[render]
width_px = 64
height_px = 48
spp = 4
noise = 1.0  # tiny test renders: any noise passes (tests/test_convergence.py checks it)
"""


def run(tmp_path, name: str, gloss: str):
    design = tmp_path / "d.toml"
    design.write_text(SMALL.format(name=name.replace('"', '\\"'), gloss=gloss))
    out = tmp_path / "out"
    result = runner.invoke(app, ["design", str(design), "-o", str(out), "--quiet"])
    return result, design, out


@pytest.fixture(scope="module")
def passed(tmp_path_factory):
    result, design, out = run(tmp_path_factory.mktemp("report"), NAME, "[1.0, 200.0]")
    assert result.exit_code == 0, result.output
    manifest = json.loads((out / "manifest.json").read_text())
    return design, out, manifest, (out / "report.html").read_text(encoding="utf-8")


class Page(HTMLParser):
    """What a browser would see: the title, headings, tags with their attributes."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []
        self.title = ""
        self.headings: list[str] = []
        self._in: str | None = None

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        if tag in ("title", "h2"):
            self._in = tag
            if tag == "h2":
                self.headings.append("")

    def handle_endtag(self, tag):
        if tag == self._in:
            self._in = None

    def handle_data(self, data):
        if self._in == "title":
            self.title += data
        elif self._in == "h2":
            self.headings[-1] += data


def parse(text: str) -> Page:
    page = Page()
    page.feed(text)
    return page


def images(page: Page) -> list[Image.Image]:
    out = []
    for tag, attrs in page.tags:
        if tag == "img":
            src = attrs["src"]
            assert src.startswith("data:image/png;base64,")
            data = base64.b64decode(src.split(",", 1)[1], validate=True)
            assert data[:8] == b"\x89PNG\r\n\x1a\n"
            out.append(Image.open(io.BytesIO(data)))
    return out


def test_report_is_written_and_listed(passed):
    _, out, manifest, _ = passed
    assert (out / "report.html").is_file()
    assert "report.html" in manifest["outputs"]
    assert {"sweep", "report", "render"} <= set(manifest["stages_s"])


def test_report_has_every_section_with_the_runs_facts(passed):
    _, _, manifest, text = passed
    page = parse(text)
    headings = " | ".join(page.headings)
    for section in (
        "Design",
        "Preview",
        "Light sweep",
        "BRDF",
        "Appearance against the targets",
        "Verification checks",
        "Mesh",
        "Slicing",
        "Timings",
        "Versions",
    ):
        assert section in headings, section
    render = manifest["render"]
    assert html.escape(render["representation_reason"]) in text
    assert f"<td>{render['representation']}</td>" in text
    assert f"{manifest['triangles']:,}" in text
    assert f"<td>{manifest['printer']['layers']}</td>" in text
    assert f"{manifest['as_printed']['rms_height_error_um']} µm" in text
    for stage in set(manifest["stages_s"]) - {"report"}:  # (the report cannot time its own writing)
        assert f"<td>{stage}</td>" in text
    assert f"<td>{manifest['versions']['mitsuba']}</td>" in text
    # The resolved TOML in a <pre>, and the gloss target met.
    assert re.search(r"<pre>[^<]*\[appearance\]\ngloss_60 = \[", text)
    assert re.search(
        r"<td>gloss_60</td><td[^>]*>[\d.]+ GU</td><td>\[1, 200\] GU</td><td[^>]*>pass</td>", text
    )


def test_images_are_embedded_pngs_of_the_right_size(passed):
    _, out, _, text = passed
    preview, sweep, brdf = images(parse(text))
    assert preview.size == (64, 48)
    assert sweep.size == (6 * 64, 48)  # six frames, each no larger than the preview
    assert brdf.size[0] > 400 and brdf.size[1] > 400
    embedded = base64.b64decode(re.search(r'src="data:image/png;base64,([^"]+)"', text).group(1))
    assert embedded == (out / "preview.png").read_bytes()
    # The sweep's frames differ: the light moves.
    strip = np.asarray(sweep.convert("L"), dtype=float)
    frames = [strip[:, 64 * k : 64 * (k + 1)].mean() for k in range(6)]
    assert max(frames) - min(frames) > 1.0 and min(frames) > 10.0  # and none is black


def test_report_references_nothing_outside_itself(passed):
    _, _, _, text = passed
    page = parse(text)
    for tag, attrs in page.tags:
        assert tag not in ("script", "link", "iframe", "object", "embed")
        for key in ("src", "href"):
            value = attrs.get(key)
            if value is not None:
                assert value.startswith(("data:image/png;base64,", "#")), (tag, value[:40])
    assert not re.search(r"(src|href)\s*=\s*[\"']?\s*(https?:)?//", text)
    assert "@import" not in text and "url(" not in text


def test_design_text_is_escaped(passed):
    _, _, _, text = passed
    page = parse(text)
    assert page.title == f"printapp report: {NAME}"
    assert "<script" not in text
    assert html.escape(NAME) in text


def test_metric_rows_measure_the_miss():
    design = load_design_text(
        "[appearance]\nroughness = [0.1, 0.3]\ngloss_60 = [70, 80]\nhaze = [0, 10]\nanisotropy = [1, 2]\n"
    )
    manifest = {
        "appearance": {"roughness": 0.5, "anisotropy": None},
        "brdf": {"gloss_gu": {"20": 40.0, "60": 63.0, "85": 90.0}, "haze": 23.0},
    }
    rows = {r["metric"]: r for r in metric_rows(design, manifest)}
    assert rows["roughness"]["verdict"] == "miss" and rows["roughness"]["miss"] == pytest.approx(0.2)
    assert rows["gloss_60"]["verdict"] == "miss" and rows["gloss_60"]["miss"] == pytest.approx(7.0)
    assert rows["haze"]["verdict"] == "miss" and rows["haze"]["miss"] == pytest.approx(13.0)
    assert rows["anisotropy"]["verdict"] == "not predicted"
    assert rows["gloss_20"]["verdict"] == "no target"
    # Haze where ASTM D4039 does not define it: n/a, the reason, and the target unchecked.
    why = "n/a: the 60-degree gloss 63.0 GU is not above the 70 GU from which ASTM D4039 defines haze"
    manifest["brdf"] = {**manifest["brdf"], "haze": None, "haze_reason": why}
    rows = {r["metric"]: r for r in metric_rows(design, manifest)}
    assert rows["haze"]["value"] is None
    assert rows["haze"]["verdict"].startswith(why) and "cannot be checked" in rows["haze"]["verdict"]


def test_sweep_is_small_and_never_larger_than_the_preview():
    def settings(render: str):
        return sweep_settings(load_design_text(f"[render]\n{render}\n"))

    assert settings("") == {"frames": 6, "width_px": 160, "height_px": 120, "spp": 8}
    assert settings("width_px = 64\nheight_px = 48\nspp = 4") == {
        "frames": 6,
        "width_px": 64,
        "height_px": 48,
        "spp": 4,
    }
    wide = settings("width_px = 800\nheight_px = 200\nspp = 256")
    assert (wide["width_px"], wide["height_px"], wide["spp"]) == (160, 40, 32)


def load_design_text(text: str):
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "d.toml"
        path.write_text(text)
        return load_design(path)


def test_report_without_a_render_says_so(passed):
    design, _, manifest, _ = passed
    text = report_html(load_design(design), {**manifest, "render": None})
    assert text.count("Not rendered in this run.") == 2 and "<img" not in text


def test_report_gives_the_samples_and_where_they_varied(passed):
    design, _, manifest, text = passed
    noise = manifest["render"]["noise"]
    low, high = noise["spp_range"]
    assert low <= manifest["render"]["spp"] <= high
    varied = {**noise, "spp_range": [40, 2736]}
    other = report_html(load_design(design), {**manifest, "render": {**manifest["render"], "noise": varied}})
    assert f"{manifest['render']['spp']} on average over the object, from 40 to 2736" in other
    alike = {**noise, "spp_range": [manifest["render"]["spp"]] * 2}
    same = report_html(load_design(design), {**manifest, "render": {**manifest["render"], "noise": alike}})
    assert f"<th>samples per pixel</th><td>{manifest['render']['spp']}</td>" in same


def test_missed_gloss_target_exits_3_and_the_report_says_by_how_much(tmp_path):
    result, _, out = run(tmp_path, "too matte", "[95.0, 100.0]")
    assert result.exit_code == 3
    assert not (out / "model.stl").exists()
    manifest = json.loads((out / "manifest.json").read_text())
    reason = next(r for r in manifest["verification"]["reasons"] if r.startswith("gloss_60"))
    miss = re.search(r"misses the target \[95, 100\] by ([\d.]+)", reason).group(1)
    text = (out / "report.html").read_text(encoding="utf-8")
    assert "Failed verification" in text and "No printable model was written" in text
    assert html.escape(reason) in text
    row = re.search(r"<td>gloss_60</td>.*?</tr>", text).group(0)
    assert f"miss: {miss} GU below the range" in row
    assert float(miss) == pytest.approx(95.0 - manifest["brdf"]["gloss_gu"]["60"], abs=0.051)


@pytest.mark.skipif(shutil.which("chromium") is None, reason="Debian's chromium is not installed")
def test_report_in_a_headless_browser(passed, tmp_path):
    _, out, _, _ = passed
    url = (out / "report.html").resolve().as_uri()
    common = [
        "chromium",
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--enable-logging=stderr",
        "--v=0",
    ]
    shot = tmp_path / "shot.png"
    result = subprocess.run(
        [*common, f"--screenshot={shot}", "--window-size=1200,2000", url],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    # A console message (a script error, a resource that failed to load) would show here.
    assert "CONSOLE" not in result.stderr and "Failed to load resource" not in result.stderr
    pixels = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert pixels.shape == (2000, 1200)
    assert pixels.std() > 20.0  # text, tables and images, not a blank page
    dom = subprocess.run([*common, "--dump-dom", url], capture_output=True, text=True, timeout=120)
    assert dom.returncode == 0, dom.stderr[-2000:]
    assert "CONSOLE" not in dom.stderr
    page = parse(dom.stdout)
    assert page.title == f"printapp report: {NAME}"
    assert len(images(page)) == 3
