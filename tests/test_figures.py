"""The one way figures are written: both formats, atomically, the figure closed."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from granpipe.figures import save_figure  # noqa: E402


def test_save_figure_writes_png_and_pdf_and_closes(tmp_path):
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    paths = save_figure(fig, tmp_path / "fig9_a.b")  # a dot in the stem stays in the name
    assert [p.name for p in paths] == ["fig9_a.b.png", "fig9_a.b.pdf"]
    assert paths[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert paths[1].read_bytes()[:5] == b"%PDF-"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig9_a.b.pdf", "fig9_a.b.png"]
    assert not plt.fignum_exists(fig.number)
