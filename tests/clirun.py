"""The command line run in-process, and the shape every refusal must have: shared by the CLI tests."""
import pytest

from nurbsinterp.cli import main


def run_plan(capsysbinary, *args):
    """`nurbsinterp plan ...` in-process: (exit code, stdout bytes, stderr text)."""
    with pytest.raises(SystemExit) as info:
        main(["plan", *map(str, args)])
    out, err = capsysbinary.readouterr()
    code = info.value.code
    return (0 if code is None else code), out, err.decode()


def assert_one_line_error(code, out, err, *parts, status=2):
    """Exit *status*, nothing on stdout, one line on stderr naming every one of *parts*, no traceback."""
    if isinstance(out, bytes):
        out, err = out.decode(), err.decode()
    assert code == status, (code, err)
    assert out == "", f"stdout is not empty: {out[:200]!r}"
    assert "Traceback" not in err
    assert err.endswith("\n") and err.count("\n") == 1, f"stderr is not one line: {err!r}"
    assert err.startswith("nurbsinterp"), err
    for part in parts:
        assert str(part) in err, f"{part!r} not in {err!r}"
    return err
