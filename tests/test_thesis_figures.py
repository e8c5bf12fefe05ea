"""The thesis's published figures live in one data file (study/reporting/thesis_figures.toml) that
the report reads: its values are the thesis's (Oliveros 2018, §5.2 and Table 5.1, copied by hand here),
and a malformed file is refused naming the file, the table and the scenes."""
import pytest

from study.reporting import thesis


def test_the_figures_are_the_thesis_s():
    assert thesis.THESIS_COLUMNS == ("No AA", "FXAA", "SMAA", "Uncharted", "Improved")
    assert thesis.THESIS_STATIC_PSNR["pipe"] == (38.782, 42.601, 47.066, 36.487, 46.162)
    assert thesis.THESIS_STATIC_PSNR["hairball_lit"] == (17.009, 20.002, 18.848, 16.535, 24.579)
    assert thesis.THESIS_STATIC_SSIM["flowers"] == (0.959, 0.975, 0.972, 0.863, 0.985)
    assert len(thesis.THESIS_STATIC_PSNR) == len(thesis.THESIS_STATIC_SSIM) == 9
    assert thesis.THESIS_GHOST_MSE == {"sphere_ghosting": (28.634, 19.501),
                                       "hairball_rotating_unlit": (81.887, 38.534),
                                       "hairball_rotating_lit": (875.687, 671.202)}
    assert thesis.THESIS_GHOST_FRAMES == 100
    sharpen = thesis.figures()["sharpen_test"]
    assert sharpen["psnr"] == [26.391, 38.669, 26.427, 38.980]
    assert sharpen["mse"] == [149.271, 8.835, 148.036, 8.224]


def test_a_malformed_file_names_the_table_and_scene(tmp_path, monkeypatch):
    bad = tmp_path / "thesis_figures.toml"
    text = thesis.FIGURES_FILE.read_text().replace("pipe = [38.782, 42.601, 47.066, 36.487, 46.162]",
                                                   "pipe = [38.782, 42.601]")
    bad.write_text(text)
    monkeypatch.setattr(thesis, "FIGURES_FILE", bad)
    thesis.figures.cache_clear()
    try:
        with pytest.raises(ValueError, match=r"thesis_figures.toml: \[static_psnr\] \['pipe'\]: need 5 values"):
            thesis.figures()
    finally:
        monkeypatch.undo()
        thesis.figures.cache_clear()
