"""Write the bundled synthetic stand-ins for the paper's five samples to data/synthetic/.

Run from the repository root: ``python scripts/make_synthetic.py``. The noise model and
geometry are documented in `brdfjax.data.synthetic`; each sample has its own fixed seed, so the
files are reproducible bit for bit.
"""

from pathlib import Path

from brdfjax.data.formats import save
from brdfjax.data.synthetic import paper_sample
from brdfjax.models.paper import PAPER_SAMPLES

OUT = Path(__file__).resolve().parents[1] / "data" / "synthetic"

if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    for seed, sample in enumerate(PAPER_SAMPLES, start=1):
        data = paper_sample(sample, seed=seed)
        save(data, OUT / f"{sample}.csv")
        print(f"{sample}: {len(data)} points, seed {seed}")
