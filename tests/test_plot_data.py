"""The figures of out-of-plane, scattered and spectral data: drawn, and refusing misuse."""

from pathlib import Path

import numpy as np
import pytest

from brdfjax.formats import load
from brdfjax.plot import plot_hemisphere, plot_polar_maps, plot_spectral

REPO = Path(__file__).resolve().parents[1]
PTFE = REPO / "data" / "real" / "nist-germer-ptfe"


def is_png(path) -> bool:
    return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 20000


@pytest.mark.parametrize("name,options", [("PTFE.data.csv", {"wavelength_nm": 532}),
                                          ("PTFE.data.random.csv", {})])
def test_polar_maps_of_grid_and_scattered_data(tmp_path, name, options):
    data = load(PTFE / name, **options)
    predicted = np.full(len(data), np.median(data.brdf))
    plot_polar_maps(data, predicted, tmp_path / "maps.png", title=name)
    assert is_png(tmp_path / "maps.png")


def test_polar_maps_need_one_prediction_per_point(tmp_path):
    data = load(PTFE / "PTFE.data.random.csv")
    with pytest.raises(ValueError, match="predicted has 3 values, the data 1760"):
        plot_polar_maps(data, [1.0, 2.0, 3.0], tmp_path / "maps.png")


def test_hemisphere_and_spectral_figures(tmp_path):
    from brdfjax.model import PAPER_SAMPLES

    plot_hemisphere(PAPER_SAMPLES["white_paint"], [10, 60], tmp_path / "h.png",
                    resolution=31)
    records = [{"wavelength_nm": w, "params": {"kb": 0.1 * k + 0.1, "b": -20.0 + k},
                "std": {"kb": 0.01, "b": None}} for k, w in enumerate((351, 532, 633))]
    records.append({"wavelength_nm": 1064, "params": {"kb": 0.5, "b": -15.0}})
    plot_spectral(records, tmp_path / "s.png", ["kb", "b"])
    assert is_png(tmp_path / "h.png") and is_png(tmp_path / "s.png")
