"""``skyfuse eval --score-area``: the polygons read from TOML or inline, bad ones as a
clear usage error (no traceback); a sensor's unconfirmed measured reports as its input."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.services.asterix.cat010 import Cat010Report
from skyfuse.services.cli.main import main
from skyfuse.services.evaluation.inputs import InputError
from skyfuse.services.evaluation.reference_area import read_score_area

SQUARE = "[[41.0, 2.0], [41.0, 2.1], [41.1, 2.1], [41.1, 2.0]]"


def test_polygons_from_toml_and_inline(tmp_path):
    f = tmp_path / "area.toml"
    f.write_text(
        f'[[area]]\nname = "rwy"\nvertices = {SQUARE}\n'
        "[[area]]\nvertices = [[41.2, 2.0], [41.2, 2.1], [41.3, 2.05]]\n"
    )
    polys = read_score_area([str(f), "41.5 2.0; 41.5 2.1 ; 41.6 2.05"])
    assert [p.name for p in polys[:2]] == ["rwy", "area.toml[1]"]
    assert polys[0].vertices.tolist() == [[41.0, 2.0], [41.0, 2.1], [41.1, 2.1], [41.1, 2.0]]
    assert polys[2].vertices.tolist() == [[41.5, 2.0], [41.5, 2.1], [41.6, 2.05]]
    assert read_score_area([]) == [] and read_score_area(None) == []


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[[area]\nvertices = 1", "not valid TOML"),
        ("name = 'x'\n", "needs one or more [[area]] tables"),
        ("[[area]]\nname = 'a'\n", "no vertices"),
        ("[[area]]\nvertices = [[41.0, 2.0], [41.1, 2.0]]\n", "2 vertices"),
        ("[[area]]\nvertices = [[41.0, 2.0], [41.1, 2.0], [41.1]]\n", "vertex 2 = [41.1]"),
        ("[[area]]\nvertices = [[41.0, 2.0], [41.1, 2.0], [95.0, 2.0]]\n", "latitude must be"),
        ("[[area]]\nvertices = [[41.0, 2.0], [41.1, 2.0], ['a', 2.0]]\n", "vertex 2"),
        ("[[area]]\nvertices = 'none'\n", "str vertices"),
    ],
)
def test_bad_polygons_are_clear_errors(tmp_path, text, message):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(InputError) as e:
        read_score_area([str(f)])
    assert message in str(e.value) and e.value.usage


def test_bad_inline_polygon_and_missing_file():
    with pytest.raises(InputError, match="vertex 1"):
        read_score_area(["41.0 2.0; 41.1; 41.2 2.0"])
    with pytest.raises(InputError, match="no such file"):
        read_score_area(["/nonexistent/area.toml"])


def test_the_command_reports_a_bad_area_without_a_traceback(tmp_path, capsys):
    f = tmp_path / "bad.toml"
    f.write_text("[[area]]\nvertices = [[41.0, 2.0], [41.1, 2.0]]\n")
    code = main(
        [
            "eval",
            "--sensor-tracks",
            str(tmp_path / "s.ast"),
            "--reference",
            str(tmp_path / "r.ast"),
            "--score-area",
            str(f),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "configuration error" in err and "2 vertices" in err
    assert "Traceback" not in err


def test_unconfirmed_measured_reports_are_the_sensors_input():
    from skyfuse.services.evaluation.sensor_tracks import _unconfirmed_measured
    from skyfuse.services.evaluation.surveillance_positions import cat010_positions

    reps = [
        Cat010Report(0, 7, 0.0, typ=3, x_m=1.0, y_m=2.0, track_number=1),  # an update
        Cat010Report(0, 7, 0.0, typ=3, x_m=1.0, y_m=2.0, track_number=1, confirmed=False),
        Cat010Report(
            0, 7, 0.0, typ=3, x_m=1.0, y_m=2.0, track_number=1, confirmed=False, coasted=3
        ),
        Cat010Report(
            0, 107, 0.0, typ=1, x_m=1.0, y_m=2.0, track_number=1, rab=True, confirmed=False
        ),
        Cat010Report(0, 7, 0.0, typ=3, track_number=1, confirmed=False),  # no position
    ]
    got = _unconfirmed_measured(reps, cat010_positions(reps))
    assert got.tolist() == [False, True, False, False, False]
    assert isinstance(got, np.ndarray)
