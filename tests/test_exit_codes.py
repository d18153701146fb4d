"""Exit codes as docs/cli.md's table says, where two commands used to disagree (issue 26).

The table itself is tested against ``meshtool.cli.output.EXIT_CODES`` in ``tests/test_cli_vocabulary.py``;
these are the cases that mapped errors elsewhere.
"""

from __future__ import annotations

from pathlib import Path

from bounded import run_bounded

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "fixtures" / "scenes"


def test_obj2bin_of_a_folder_without_an_output_is_a_usage_error(tmp_path: Path) -> None:
    out = run_bounded(["obj2bin", str(ROOT / "fixtures" / "head")])
    assert out.code == 2 and "a folder needs -o OUTDIR" in out.err and "Traceback" not in out.err


def test_simrun_play_with_a_video_of_another_kind_is_a_usage_error(tmp_path: Path) -> None:
    out = run_bounded(["simrun", "play", str(SCENES / "basic.toml"), "--video", str(tmp_path / "o.avi")])
    assert out.code == 2
    assert out.err == f"error: {tmp_path / 'o.avi'}: video must end in .gif or .mp4\n"


def test_simrun_test_of_a_missing_path_is_exit_1_and_of_a_bad_option_exit_2(tmp_path: Path) -> None:
    missing = run_bounded(["simrun", "test", str(tmp_path / "nowhere")])
    assert missing.code == 1 and missing.err == f"error: {tmp_path / 'nowhere'}: no such file or folder\n"
    bad = run_bounded(["simrun", "test", str(SCENES / "basic.toml"), "--seeds", "x"])
    assert bad.code == 2
    assert bad.err == "usage error: --seeds 'x': expected START:STOP, N or N1,N2,... (integers)\n"


def test_validate_maps_a_meshtool_error_to_exit_1_not_internal(monkeypatch, tmp_path: Path) -> None:
    """A plain MeshtoolError from the run was exit 3 ("internal") in validate and exit 1 everywhere else."""
    from click.testing import CliRunner

    import meshtool.cli.validate
    from meshtool.cli.main import main
    from meshtool.errors import MeshtoolError

    def refuse(*_args: object, **_kwargs: object) -> None:
        raise MeshtoolError("is not readable", path="a.obj", hint="check it")

    monkeypatch.setattr(meshtool.cli.validate, "run_validate", refuse)
    (tmp_path / "a.obj").write_text("v 0 0 0\n")
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "a.obj"), "--no-cache"])
    assert result.exit_code == 1, result.output
    assert "error: a.obj: is not readable (check it)" in result.output
