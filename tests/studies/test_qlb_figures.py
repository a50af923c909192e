"""The QLB figure script (``python -m studies.qlb_figures``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def test_figure_script_writes_nontrivial_pngs(tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    out = tmp_path / "figs"
    proc = subprocess.run(
        [sys.executable, "-m", "studies.qlb_figures", "--out", str(out), "--grid", "21", "--dpi", "60"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "fig03_cbm_far.png",
        "fig04_qlb_far.png",
        "fig05_cbm_mid.png",
        "fig06_qlb_mid.png",
        "fig07_cbm_near.png",
        "fig08_qlb_near.png",
        "fig10_update_ped_ped.png",
        "fig11_update_vehicle_ped.png",
    ]
    for name in names:
        img = mpimg.imread(out / name)
        assert img.ndim == 3 and img.shape[0] >= 200 and img.shape[1] >= 300, name
        assert float(img[..., :3].std()) > 0.05, f"{name} looks blank"


def test_figure_script_rejects_a_file_as_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from studies import qlb_figures

    target = tmp_path / "not_a_dir.png"
    target.write_text("x")
    with pytest.raises(SystemExit) as exc:
        qlb_figures.main(["--out", str(target)])
    assert exc.value.code == 2
    assert "not a directory" in capsys.readouterr().err
    assert target.read_text() == "x"
