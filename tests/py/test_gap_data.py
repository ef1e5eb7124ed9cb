"""bench/gap/data/ holds only what the tool reads at run time.

It is package data (shipped in the wheel with bench/): the committed null
calibrations and the bundled reality run with its key. A campaign's results
(scores, per-run tables, keys and answers, preregistered hashes) belong
beside the record that cites them, in docs/results/data/
(docs/results/README.md, "How a record is written").
"""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "bench" / "gap" / "data"


def test_every_file_of_the_package_data_is_read_by_the_code():
    code = "\n".join(p.read_text() for p in (ROOT / "bench").rglob("*.py"))
    unread = sorted(p.name for p in DATA.iterdir() if p.is_file() and p.name not in code)
    assert not unread, (
        f"files in bench/gap/data/ that no module names (campaign results go to docs/results/data/): {unread}"
    )
