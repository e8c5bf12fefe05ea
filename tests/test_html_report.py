"""The interactive comparison report (study.reporting.html_report): the page and its data without a browser,
then in headless Chromium (Debian's chromium through its chromium-driver): no console errors,
flipping shows the expected technique's pixels, zoom enlarges pixels, maps one key away, exposure,
ghosting slider and curve, sortable tables whose links open the viewer. One real tiny study
(taa-study run) supplies the report the browser checks first."""
import io
import json
import math
import os
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from study.reporting import html_report
from study.reporting.encode import slug
from study.reporting.html_report import ReportDataError

sys.path.insert(0, str(Path(__file__).parent))
from study_fixtures import run_tiny_study  # noqa: E402


def _png(path: Path, arr) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.asarray(arr, np.uint8)).save(path)


W, H, NF = 32, 24, 4
COLOURS = {"Reference": (60, 60, 60), "No AA": (200, 40, 40), "Improved": (40, 160, 60)}
GREY = 128          # the Improved FLIP map's level, for the exposure check


def fake_study(out: Path, label_b: str = "Improved") -> dict:
    """Fake PNGs and the `data` that names them: a 1-pixel checker on each technique's colour (so
    every image pixel differs from its neighbours), flat maps, and 4-frame ghosting sequences whose
    frames differ in red."""
    yy, xx = np.mgrid[:H, :W]
    chk = ((xx + yy) % 2)[..., None] * 40
    techs = {}
    for i, label in enumerate(["No AA", label_b]):
        s = slug(label) or f"t{i}"
        _png(out / f"images/static_tiny_{s}.png", np.array(COLOURS[["No AA", "Improved"][i]]) + chk)
        _png(out / f"maps/static_tiny_{s}_ssim.png", np.full((H, W), 100 + 100 * i))
        _png(out / f"maps/static_tiny_{s}_flip.png", np.full((H, W, 3), GREY))
        techs[label] = {"image": f"images/static_tiny_{s}.png", "ssim_map": f"maps/static_tiny_{s}_ssim.png",
                        "flip_map": f"maps/static_tiny_{s}_flip.png",
                        "metrics": {"psnr": 30.0 + i, "ssim": 0.9 + i / 20, "flip_ldr": 0.1 - i / 50,
                                    "mse": math.nan}}
    _png(out / "images/static_tiny_reference.png", np.array(COLOURS["Reference"]) + chk)
    ghost = {"frames": [10, 11, 12, 13], "reference": [], "techniques": {}}
    for f in range(NF):
        p = f"images/ghosting_tiny_reference_f{f:04d}.png"
        _png(out / p, np.full((H, W, 3), 20 + 50 * f))
        ghost["reference"].append(p)
    for i, label in enumerate(["No AA", label_b]):
        paths = []
        for f in range(NF):
            p = f"images/ghosting_tiny_t{i}_f{f:04d}.png"
            _png(out / p, np.broadcast_to(np.array([20 + 50 * f, 100 * i, 30]), (H, W, 3)))
            paths.append(p)
        ghost["techniques"][label] = {"images": paths, "metrics": {"psnr": [30.0 + f + i for f in range(NF)],
                                                                   "mse": [10.0, None, 8.0, 7.0]}}
    return {"title": "Fake study", "profile": "quick", "resolution": {"tiny": [W, H]},
            "scenes": {"tiny": {"agreement": {"agreement_psnr_db": 47.25, "reference_spp": 512},
                                "reference_bound": "every pixel's SE <= 0.5 LSB",
                                "static": {"thesis (16 frames, cold)": {"reference": "images/static_tiny_reference.png",
                                                                        "techniques": techs}},
                                "ghosting": {"ghosting": ghost}}},
            "tables": {"headline": {"title": "Headline", "header": ["scene", "protocol", "No AA", label_b, "best"],
                                    "rows": [["tiny", "thesis", "30.000 / 0.9", "31.000 / 0.95", label_b],
                                             ["big", "thesis", "9.5 / 0.1", "100.0 / 0.99", label_b],
                                             ["mid", "thesis", "–", "∞", label_b]],
                                    "links": [[0, 2, techs["No AA"]["image"]], [0, 3, techs[label_b]["image"]],
                                              [2, 2, techs["No AA"]["flip_map"]]]}}}


def page_model(page: str) -> dict:
    m = re.search(r'<script type="application/json" id="taa-data">(.*?)</script>', page, re.S)
    return json.loads(m.group(1))


# -- without a browser ---------------------------------------------------------------------------------
def test_page_is_self_contained_and_keeps_the_techniques_order(tmp_path):
    data = fake_study(tmp_path)
    target = html_report.write(tmp_path, data)
    assert target == tmp_path / "report.html"
    page = target.read_text()
    # Nothing fetched from elsewhere: no external script, style sheet or URL (the SVG namespace is a name).
    assert not re.search(r"<script[^>]+src=", page) and not re.search(r"<link[^>]+stylesheet", page)
    assert set(re.findall(r"https?://[^\s\"'<>]+", page)) == {"http://www.w3.org/2000/svg"}
    model = page_model(page)
    static, ghost = model["viewers"]
    # The layers are a list: sorted keys (Jinja's tojson default) would put "Improved" before "No AA".
    assert [L["label"] for L in static["layers"]] == ["Reference", "No AA", "Improved"]
    assert static["layers"][1]["images"] == ["images/static_tiny_no_aa.png"]
    assert static["layers"][2]["ssim"] == "maps/static_tiny_improved_ssim.png"
    assert static["layers"][1]["metrics"]["mse"] is None             # NaN: null in strict JSON
    assert ghost["kind"] == "ghosting" and ghost["frames"] == [10, 11, 12, 13]
    assert ghost["layers"][2]["metrics"]["mse"] == [10.0, None, 8.0, 7.0]
    for rel in re.findall(r'(?:images|maps)/[\w.]+\.png', page):
        assert (tmp_path / rel).is_file(), rel
    assert "47.25" in page and "every pixel&#39;s SE &lt;= 0.5 LSB" in page   # agreement and bound
    assert '<a href="maps/static_tiny_no_aa_flip.png"' in page                 # a linked table cell


def test_labels_are_escaped_in_the_page_and_survive_in_its_data(tmp_path):
    label = '<img src=x onerror=alert(1)>&"'
    page = html_report.write(tmp_path, fake_study(tmp_path, label_b=label)).read_text()
    assert label not in page
    assert "&lt;img src=x onerror=alert(1)&gt;&amp;&#34;" in page
    assert page_model(page)["viewers"][0]["layers"][2]["label"] == label


@pytest.mark.parametrize("edit, words", [
    (lambda d: d["scenes"]["tiny"]["static"]["thesis (16 frames, cold)"]["techniques"]["No AA"]
     .update(image="images/nope.png"), ["techniques.No AA.image = images/nope.png", "missing"]),
    (lambda d: d["scenes"]["tiny"]["ghosting"]["ghosting"]["reference"].pop(),
     ["scenes.tiny.ghosting.ghosting.reference", "expected 4 paths"]),
    (lambda d: d["scenes"]["tiny"]["ghosting"]["ghosting"]["techniques"]["No AA"]["metrics"]["psnr"].append(1.0),
     ["techniques.No AA.metrics.psnr", "expected 4 values"]),
    (lambda d: d["tables"]["headline"]["links"].append([3, 0, "images/static_tiny_reference.png"]),
     ["tables.headline.links[3]", "inside the table"]),
    (lambda d: d["tables"]["headline"]["rows"][1].pop(), ["tables.headline.rows[1]", "expected 5 cells"]),
    (lambda d: d["resolution"].pop("tiny"), ["resolution.tiny", "missing"]),
    (lambda d: d["scenes"]["tiny"]["static"]["thesis (16 frames, cold)"].update(reference="/etc/passwd"),
     ["reference", "relative"]),
])
def test_bad_data_is_refused_naming_the_field(tmp_path, edit, words):
    data = fake_study(tmp_path)
    edit(data)
    with pytest.raises(ReportDataError) as exc:
        html_report.write(tmp_path, data)
    for w in words:
        assert w in str(exc.value)
    assert not (tmp_path / "report.html").exists()


# -- a real tiny study ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory, reference_pool):
    """A real study of the two tiny scenes (No AA and the baseline TAA) and its report. Where the
    study does not write report.html itself yet, the report is built here from its folder."""
    out = run_tiny_study(tmp_path_factory.mktemp("html_study"), "noaa", "taa_baseline", pool=reference_pool)
    page = out / "report.html"
    hooked = page.exists()
    if not hooked:
        print("note: taa-study run wrote no report.html; building it with html_report.write(out, collect(out))")
        html_report.write(out, html_report.collect(out))
    return out, hooked


def _csv(path: Path) -> list[list[str]]:
    import csv
    return list(csv.reader(path.read_text().splitlines()))


@pytest.mark.long(seconds=17)
def test_collect_reads_a_finished_study(tiny_study):
    out, _ = tiny_study
    data = html_report.collect(out)
    assert sorted(data["scenes"]) == ["tiny_moving", "tiny_still"]
    assert data["resolution"] == {"tiny_moving": [40, 24], "tiny_still": [36, 20]}
    still = data["scenes"]["tiny_still"]
    assert list(still["static"]) == ["thesis (16 frames, cold)", "converged (256 frames)"]
    thesis = still["static"]["thesis (16 frames, cold)"]
    assert list(thesis["techniques"]) == ["noaa", "taa_baseline"]
    table = {r[0]: r for r in _csv(out / "tables/static_tiny_still.csv")}
    for i, label in enumerate(["noaa", "taa_baseline"], start=1):
        t = thesis["techniques"][label]
        assert t["image"] == f"images/static_tiny_still_{label}.png"
        assert t["ssim_map"] == f"maps/static_tiny_still_{label}_ssim.png"
        assert t["metrics"]["psnr"] == float(table["PSNR (dB)"][i])
        assert t["metrics"]["ssim"] == float(table["SSIM"][i])
    assert "0.5 LSB" in still["reference_bound"]
    assert "plots/history_convergence_tiny_still.png" in still["plots"]
    # headline: rows are (scene, protocol) in the study's order; each technique cell opens its image
    head = data["tables"]["headline"]
    links = {(r, c): p for r, c, p in head["links"]}
    for r, row in enumerate(head["rows"]):
        stem = "static" if row[1].startswith("thesis") else "static_converged"
        for c, label in ((2, "noaa"), (3, "taa_baseline")):
            assert links[(r, c)] == f"images/{stem}_{row[0]}_{label}.png"
    # the static table's SSIM row opens the SSIM map
    st = data["tables"]["static_tiny_still"]
    ssim_row = [r for r, row in enumerate(st["rows"]) if row[0] == "SSIM"][0]
    assert [p for r, c, p in st["links"] if (r, c) == (ssim_row, 2)] == ["maps/static_tiny_still_taa_baseline_ssim.png"]



@pytest.mark.long(seconds=17)
def test_each_technique_s_maps_and_image_are_its_own(tiny_study):
    """The report makes its images on a thread pool, after the loop that plans them: every map file
    holds the maps its own technique's metrics filed (not the loop's last technique's), and the
    SSIM PNG is that map at 8 bits."""
    import json
    from PIL import Image
    from references.exr import read_exr
    out, _ = tiny_study
    arts = json.loads((out / "manifest.json").read_text())["artefacts"]
    cache = out.parent / "cache"
    checked = set()
    for rel, entry in arts.items():
        if not (rel.startswith("maps/static_") and rel.endswith(".exr")):
            continue
        inputs = entry["inputs"]
        (own,) = list(cache.glob(f"metrics/*/{inputs['metrics']}/maps_{inputs['frame']:04d}.exr"))
        _, want = read_exr(own)
        _, got = read_exr(out / rel)
        assert sorted(got) == sorted(want) and all(np.array_equal(got[k], want[k]) for k in want), rel
        # the SSIM PNG is that map at 8 bits, but for the pixels painted where the reference's noise
        # exceeds its colour step (study.reporting.map_noise; tests/test_map_noise.py)
        from study.reporting.map_noise import MARK_RGB
        ssim = np.asarray(Image.open(out / rel.replace(".exr", "_ssim.png")).convert("RGB"))
        painted = np.all(ssim == MARK_RGB, axis=-1)
        grey = np.round(np.clip(want["ssim"], 0, 1) * 255).astype(np.uint8)
        assert np.array_equal(ssim[~painted], np.repeat(grey[..., None], 3, -1)[~painted]), rel
        checked.add(rel.split("_")[-1])
    assert checked >= {"noaa.exr", "baseline.exr"}, checked       # both columns' maps differ


@pytest.mark.long(seconds=17)
def test_a_study_s_maps_are_painted_as_its_marks_say(tiny_study):
    """A tiny study's static maps: the painted pixels are the ones marked.json counts, the FLIP map's
    within the SSIM map's (its threshold is higher), and the report's caption says so."""
    from study.reporting import map_noise as M
    out, _ = tiny_study
    notes = sorted(out.glob("maps/static_*_marked.json"))
    assert notes
    for p in notes:
        rec = json.loads(p.read_text())
        stem = p.name[:-len("_marked.json")]
        for kind in M.KINDS:
            maps = sorted(out.glob(f"maps/{stem}_*_{kind}.png"))
            assert maps
            for m in maps:
                rgb = np.asarray(Image.open(m).convert("RGB"))
                assert int(np.all(rgb == M.MARK_RGB, axis=-1).sum()) == rec["marked"][kind], m
        assert rec["marked"]["flip"] <= rec["marked"]["ssim"]
        assert rec["threshold_lsb"] == {k: M.threshold_lsb(k) for k in M.KINDS}
    page = (out / "report.html").read_text()
    assert page.count('class="note maps-note"') == len(notes) and "marked, not refined" in page


# -- in a browser -------------------------------------------------------------------------------------
def _browser_missing() -> str | None:
    for exe in ("chromium", "chromedriver"):
        if shutil.which(exe) is None:
            return f"{exe} is not installed (scripts/setup.sh installs Debian's chromium and chromium-driver)"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[test]')"
    return None


@pytest.fixture(scope="module")
def browser():
    why = _browser_missing()
    if why:
        print(f"skipping the browser test: {why}")
        pytest.skip(why)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium")
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1280,1400",
              "--force-device-scale-factor=1", "--no-first-run", "--disable-extensions"):
        opts.add_argument(a)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    # The Debian driver by path: Selenium Manager (which downloads drivers) is never asked.
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=opts)
    driver.set_page_load_timeout(30)
    yield driver
    driver.quit()


def _open(driver, page: Path):
    driver.get_log("browser")          # the log of earlier pages is not this page's; this page's
    driver.get(page.resolve().as_uri())  # errors may come while it loads, so clear before loading


def _console_errors(driver) -> list[str]:
    return [e["message"] for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def _viewer(driver, vid: str):
    from selenium.webdriver.common.by import By
    v = driver.find_element(By.ID, vid)
    driver.execute_script("arguments[0].scrollIntoView({block: 'start'});", v)
    v.find_element(By.TAG_NAME, "h3").click()          # makes it the viewer the keys act on
    return v


def _keys(driver, keys: str) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    ActionChains(driver).send_keys(keys).perform()


def _wait_drawn(driver, v, src: str) -> None:
    from selenium.webdriver.support.ui import WebDriverWait
    WebDriverWait(driver, 10).until(lambda d: v.get_attribute("data-src") == src and v.get_attribute("data-ready") == "1")


def _canvas(v) -> np.ndarray:
    from selenium.webdriver.common.by import By
    shot = v.find_element(By.TAG_NAME, "canvas").screenshot_as_png
    return np.asarray(Image.open(io.BytesIO(shot)).convert("RGB")).astype(int)


def _expected(img: np.ndarray, zoom: float, px: int, py: int, shape) -> tuple[np.ndarray, np.ndarray]:
    """What the canvas shows of img at (zoom, pan) with nearest-neighbour pixels, and where."""
    ys, xs = np.arange(shape[0]), np.arange(shape[1])
    iy, ix = np.floor((ys - py) / zoom).astype(int), np.floor((xs - px) / zoom).astype(int)
    inside = ((iy >= 0) & (iy < img.shape[0]))[:, None] & ((ix >= 0) & (ix < img.shape[1]))[None, :]
    return img[np.clip(iy, 0, img.shape[0] - 1)][:, np.clip(ix, 0, img.shape[1] - 1)].astype(int), inside


def _shows(v, img: np.ndarray) -> float:
    """Fraction of the image's on-canvas pixels the canvas shows exactly (within 2 levels)."""
    shot = _canvas(v)
    exp, inside = _expected(img, float(v.get_attribute("data-zoom")), int(v.get_attribute("data-px")),
                            int(v.get_attribute("data-py")), shot.shape)
    assert inside.sum() > 1000
    return float((np.abs(shot - exp).max(-1) <= 2)[inside].mean())


def test_browser_flips_zooms_and_shows_maps_on_a_tiny_study(browser, tiny_study, tmp_path):
    out, _ = tiny_study
    _open(browser, out / "report.html")
    v = _viewer(browser, "v-tiny_still-thesis_16_frames_cold")
    img = {n: np.asarray(Image.open(out / f"images/static_tiny_still_{n}.png").convert("RGB"))
           for n in ("reference", "noaa", "taa_baseline")}
    assert np.abs(img["noaa"].astype(int) - img["taa_baseline"]).max() > 20    # flipping must be visible

    _wait_drawn(browser, v, "images/static_tiny_still_reference.png")
    zoom0 = float(v.get_attribute("data-zoom"))
    assert zoom0 >= 8 and _shows(v, img["reference"]) > 0.999
    for key, name in (("2", "noaa"), ("3", "taa_baseline"), ("2", "noaa")):
        _keys(browser, key)
        _wait_drawn(browser, v, f"images/static_tiny_still_{name}.png")
        assert v.get_attribute("data-layer") == name
        other = "taa_baseline" if name == "noaa" else "noaa"
        assert _shows(v, img[name]) > 0.999 and _shows(v, img[other]) < 0.95

    _keys(browser, "s")                                   # the SSIM map of the technique shown
    _wait_drawn(browser, v, "maps/static_tiny_still_noaa_ssim.png")
    ssim = np.asarray(Image.open(out / "maps/static_tiny_still_noaa_ssim.png").convert("RGB"))
    assert _shows(v, ssim) > 0.999
    _keys(browser, "i")
    _wait_drawn(browser, v, "images/static_tiny_still_noaa.png")

    _keys(browser, "+")                                   # zoom: each image pixel covers more screen pixels
    zoom1 = float(v.get_attribute("data-zoom"))
    assert zoom1 == 2 ** (math.floor(math.log2(zoom0)) + 1) > zoom0
    assert _shows(v, img["noaa"]) > 0.999
    # Measured on the screen: every colour change along a row or column falls on the grid of screen
    # pixels an image pixel covers, so the runs between changes have that size as their GCD.
    def pixel_size(a):
        runs = [np.diff(np.flatnonzero(np.any(line[1:] != line[:-1], axis=1)))
                for line in list(a) + list(a.transpose(1, 0, 2))]
        return int(np.gcd.reduce(np.concatenate(runs)))
    size1 = pixel_size(_canvas(v))
    _keys(browser, "0")
    _wait_drawn(browser, v, "images/static_tiny_still_noaa.png")
    assert float(v.get_attribute("data-zoom")) == zoom0
    size0 = pixel_size(_canvas(v))
    assert (size0, size1) == (zoom0, zoom1)

    # The converged viewer of the same scene follows the zoom (linked views).
    _keys(browser, "+")
    w = browser.find_element("id", "v-tiny_still-converged_256_frames")
    assert w.get_attribute("data-zoom") == v.get_attribute("data-zoom")

    shot = tmp_path / "report_tiny_study.png"
    browser.save_screenshot(str(shot))
    print(f"report screenshot: {shot}")
    assert _console_errors(browser) == []


def test_browser_ghosting_exposure_and_tables(browser, tmp_path):
    data = fake_study(tmp_path)
    page = html_report.write(tmp_path, data)
    _open(browser, page)
    from selenium.webdriver.common.by import By

    v = _viewer(browser, "v-tiny-thesis_16_frames_cold")
    _wait_drawn(browser, v, "images/static_tiny_reference.png")
    _keys(browser, "3f")                                  # Improved's FLIP map: flat grey
    _wait_drawn(browser, v, "maps/static_tiny_improved_flip.png")
    _keys(browser, "i")
    _wait_drawn(browser, v, "images/static_tiny_improved.png")
    base = _canvas(v)
    px, py, z = int(v.get_attribute("data-px")), int(v.get_attribute("data-py")), float(v.get_attribute("data-zoom"))
    at = (py + int(z / 2), px + int(z / 2))               # the centre of image pixel (0, 0): checker 0
    assert tuple(base[at]) == COLOURS["Improved"]
    _keys(browser, "ee")                                  # +1 EV: linear light doubled, clipped at white
    assert v.get_attribute("data-ev") == "1"

    def srgb_decode(c):
        c = c / 255
        return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)

    def srgb_encode(x):
        x = np.clip(x, 0, 1)
        return 255 * np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    want = srgb_encode(2 * srgb_decode(np.array(COLOURS["Improved"], float)))
    got = _canvas(v)[at]
    assert np.abs(got - want).max() <= 4, (got, want)
    _keys(browser, "x")
    assert tuple(_canvas(v)[at]) == COLOURS["Improved"]

    g = _viewer(browser, "v-tiny-ghosting")
    _wait_drawn(browser, g, "images/ghosting_tiny_reference_f0000.png")
    _keys(browser, "2..")                                 # No AA, two frames on
    _wait_drawn(browser, g, "images/ghosting_tiny_t0_f0002.png")
    assert g.get_attribute("data-frame") == "2"
    assert g.find_element(By.CSS_SELECTOR, "input.slider").get_attribute("value") == "2"
    assert "id 12" in g.find_element(By.CSS_SELECTOR, ".frame-id").text
    assert tuple(_canvas(g)[int(g.get_attribute("data-py")) + 2, int(g.get_attribute("data-px")) + 2]) == (120, 0, 30)
    marker = g.find_element(By.CSS_SELECTOR, "svg.curve line.marker")
    assert marker.get_attribute("data-frame") == "2"
    lines = g.find_elements(By.CSS_SELECTOR, "svg.curve polyline")
    assert [ln.get_attribute("data-layer") for ln in lines] == ["No AA", "Improved"]
    assert "current" in lines[0].get_attribute("class")
    # PSNR 30..33: the first point of No AA sits at the bottom of the plot, Improved's last at the top
    first = [tuple(map(float, p.split(","))) for p in lines[0].get_attribute("points").split()]
    last = [tuple(map(float, p.split(","))) for p in lines[1].get_attribute("points").split()]
    assert first[0][1] == pytest.approx(150) and last[-1][1] == pytest.approx(10) and len(first) == NF

    table = browser.find_element(By.CSS_SELECTOR, 'table.sortable[data-stem="headline"]')
    col = lambda: [tr.find_elements(By.TAG_NAME, "td")[3].text for tr in table.find_elements(By.CSS_SELECTOR, "tbody tr")]  # noqa: E731
    assert col() == ["31.000 / 0.95", "100.0 / 0.99", "∞"]
    th = table.find_elements(By.TAG_NAME, "th")[3]
    browser.execute_script("arguments[0].scrollIntoView({block: 'center'});", th)
    th.click()
    assert col() == ["31.000 / 0.95", "100.0 / 0.99", "∞"] and th.get_attribute("aria-sort") == "ascending"
    th.click()
    assert col() == ["∞", "100.0 / 0.99", "31.000 / 0.95"]
    no_aa = table.find_elements(By.TAG_NAME, "th")[2]
    no_aa.click()                                         # 9.5 < 30; '–' (no value) last
    assert [tr.find_elements(By.TAG_NAME, "td")[2].text for tr in table.find_elements(By.CSS_SELECTOR, "tbody tr")] \
        == ["9.5 / 0.1", "30.000 / 0.9", "–"]
    no_aa.click()                                         # descending: the missing value stays last
    assert [tr.find_elements(By.TAG_NAME, "td")[2].text for tr in table.find_elements(By.CSS_SELECTOR, "tbody tr")] \
        == ["30.000 / 0.9", "9.5 / 0.1", "–"]
    # a linked cell opens its image in the viewer that holds it
    table.find_element(By.CSS_SELECTOR, 'a[data-img="maps/static_tiny_no_aa_flip.png"]').click()
    _wait_drawn(browser, v, "maps/static_tiny_no_aa_flip.png")
    assert v.get_attribute("data-layer") == "No AA" and v.get_attribute("data-mode") == "flip"
    assert "active" in v.get_attribute("class")
    assert _console_errors(browser) == []


def test_browser_reports_a_missing_image_as_a_console_error(browser, tmp_path):
    """The no-console-error checks above can fail: an image removed after writing is an error."""
    page = html_report.write(tmp_path, fake_study(tmp_path))
    os.remove(tmp_path / "images/static_tiny_reference.png")
    _open(browser, page)
    from selenium.webdriver.support.ui import WebDriverWait
    WebDriverWait(browser, 10).until(
        lambda d: d.find_element("id", "v-tiny-thesis_16_frames_cold").get_attribute("data-ready") == "failed")
    errors = _console_errors(browser)
    assert any("static_tiny_reference.png" in e for e in errors), errors


def test_browser_steps_a_real_ghosting_sequence(browser, tiny_study):
    """The study's own ghosting frames (written by taa-study run once it calls html_report.write):
    the slider steps frames and the canvas shows that frame's image of the technique chosen."""
    out, hooked = tiny_study
    ghosts = [v for v in page_model((out / "report.html").read_text())["viewers"] if v["kind"] == "ghosting"]
    if not hooked:
        # collect() alone has no per-frame images: nothing to step through, and the page says so by
        # having no ghosting viewer.
        print("note: the study does not write report.html itself yet; its ghosting viewers are not checked")
        assert ghosts == []
        return
    assert [v["scene"] for v in ghosts] == ["tiny_moving"]        # tiny_still is not animated
    spec = ghosts[0]
    assert [L["label"] for L in spec["layers"]] == ["Reference", "noaa", "taa_baseline"]
    assert len(spec["frames"]) >= 2 and all(len(L["images"]) == len(spec["frames"]) for L in spec["layers"])
    _open(browser, out / "report.html")
    g = _viewer(browser, spec["id"])
    _wait_drawn(browser, g, spec["layers"][0]["images"][0])
    _keys(browser, "3.")
    want = spec["layers"][2]["images"][1]
    _wait_drawn(browser, g, want)
    assert g.get_attribute("data-frame") == "1"
    assert _shows(g, np.asarray(Image.open(out / want).convert("RGB"))) > 0.999
    curve = g.find_element("css selector", "svg.curve polyline.current")
    assert curve.get_attribute("data-layer") == "taa_baseline"
    assert _console_errors(browser) == []


def test_browser_opens_on_the_findings_then_the_summary_tables_then_the_scenes(browser, tmp_path):
    data = fake_study(tmp_path)
    data["findings"] = ["The improved TAA beats Uncharted on every static scene. Thesis: 9 of 9. Here: reproduced.",
                        "The sharpen test: not reproduced."]
    data["missed"] = {"tiny": ["agreement 44.17 dB < 45 dB"]}
    data["tables"]["static_tiny"] = {"title": "Static test", "header": ["metric", "No AA"], "rows": [["PSNR", "30"]],
                                     "links": []}
    page = html_report.write(tmp_path, data)
    _open(browser, page)
    top = browser.execute_script("""
        const y = s => document.querySelector(s).getBoundingClientRect().top + window.scrollY;
        return {findings: y('#findings'), headline: y('#t-headline'), scene: y('#scene-tiny'),
                other: y('#t-static_tiny'), view: window.innerHeight,
                items: [...document.querySelectorAll('#findings li')].map(e => e.textContent),
                warn: document.querySelector('#findings .warn').textContent,
                mark: document.querySelector('#scene-tiny h2 .warn') !== null,
                floor: document.querySelector('#scene-tiny .floor p').className};""")
    assert top["findings"] < 200 and top["headline"] < top["view"]           # the first screen: the findings
    assert top["findings"] < top["headline"] < top["scene"] < top["other"]    # then the scenes, then the rest
    assert top["items"] == data["findings"]
    assert "tiny" in top["warn"] and "44.17 dB < 45 dB" in top["warn"]
    assert top["mark"] and top["floor"] == "warn"
    assert not _console_errors(browser)


LONG_LABELS = ["No AA", "FXAA", "SMAA", "Uncharted", "Improved", "Improved, no sharpen", "Uncharted, no sharpen",
               "Uncharted, normalised sharpen", "Improved, Xu sharpen", "Sparse SS", "Ferrando", "SSAA 16x"]


def _first_screen_study(out: Path) -> dict:
    """fake_study with what a real study's first screen holds: an overview figure, a seven-column
    findings table of long sentences and a headline table of twelve techniques (wider than any window)."""
    data = fake_study(out)
    _png(out / "plots/overview.png", np.full((480, 680, 3), 230))
    data["overview"] = "plots/overview.png"
    data["findings"] = [f"Claim {i}: the improved TAA beats Uncharted on every static scene of the thesis, "
                        f"by {i}.2 ± 0.1 dB here against 1.3 dB there. " * 3 for i in range(9)]
    header = ["claim", "thesis", "ours", "verdict", "cases reproduced", "against the thesis's ground truth",
              "what explains it"]
    rows = [[f"The improved TAA's PSNR beats the Uncharted TAA's on the static test, claim {i}", "+1.25 dB",
             f"+0.{i}3 dB [+0.1, +0.{i}5] over 9 scene-protocol cases", "not reproduced" if i % 2 else "reproduced",
             f"{i} / 9", f"{i} / 9 (+0.2)", "the sharpen kernel's strength explains 80 % of the difference"]
            for i in range(9)]
    data["tables"]["findings"] = {"title": "The thesis's claims", "header": header, "rows": rows, "links": []}
    data["tables"]["headline"] = {
        "title": "Headline", "header": ["scene", "protocol"] + LONG_LABELS + ["best PSNR", "± reference"],
        "rows": [[f"scene_{i}", "thesis (16 frames, cold)"] + ["31.123 ± 0.01 / 0.9512" for _ in LONG_LABELS]
                 + ["Improved, no sharpen", "0.01 / 0.0001"] for i in range(6)], "links": []}
    return data


@pytest.mark.parametrize("width", [1280, 1440, 1920])
def test_browser_first_screen_shows_the_figure_and_the_verdicts_whole(browser, tmp_path, width):
    page = html_report.write(tmp_path, _first_screen_study(tmp_path))
    size = browser.get_window_size()
    browser.set_window_size(width, 1000)
    try:
        _check_first_screen(browser, page, width)
    finally:
        browser.set_window_size(size["width"], size["height"])    # the module's other tests' window


def _check_first_screen(browser, page: Path, width: int) -> None:
    _open(browser, page)
    got = browser.execute_script("""
        const box = s => { const e = document.querySelector(s); if (!e) return null;
                           const r = e.getBoundingClientRect(); return {left: r.left, right: r.right, top: r.top + scrollY}; };
        const de = document.documentElement;
        return {inner: window.innerWidth, client: de.clientWidth, scroll: de.scrollWidth,
                verdicts: box('table.verdict'), figure: box('#overview-figure img'), prose: box('ul.findings'),
                header: [...document.querySelectorAll('table.verdict th')].map(e => e.textContent),
                verdict_cells: [...document.querySelectorAll('table.verdict td:nth-child(4)')].map(e => {
                    const r = e.getBoundingClientRect(); return r.right; })};""")
    assert got["inner"] == width
    assert got["scroll"] <= got["client"], got                     # no sideways scrolling of the page
    assert got["header"] == ["claim", "thesis", "ours", "verdict"]
    assert got["verdicts"]["right"] <= got["client"] and max(got["verdict_cells"]) <= got["client"], got
    assert got["verdicts"]["top"] < got["prose"]["top"] and got["figure"]["top"] < got["prose"]["top"]
    assert got["verdicts"]["top"] < 1000 and got["figure"]["top"] < 1000    # both begin on the first screen
    # a wide data table scrolls in its own box, its first column in view
    side = browser.execute_script("""
        const wrap = document.querySelector('#t-headline'), table = wrap.querySelector('table');
        wrap.scrollIntoView({block: 'center'});
        const before = wrap.scrollLeft; wrap.scrollLeft = 400;
        const w = wrap.getBoundingClientRect(), cell = table.querySelector('tbody tr td');
        const c = cell.getBoundingClientRect();
        const hit = document.elementFromPoint(c.left + 3, c.top + c.height / 2);
        return {overflows: table.scrollWidth > wrap.clientWidth, scrolled: wrap.scrollLeft, before,
                wrap_left: w.left, cell_left: c.left, on_top: hit === cell || cell.contains(hit),
                wrap_right: w.right};""")
    assert side["overflows"] and side["scrolled"] > 0 and side["before"] == 0, side
    assert abs(side["cell_left"] - side["wrap_left"]) <= 2 and side["on_top"], side
    assert side["wrap_right"] <= got["client"]
    assert not _console_errors(browser)
