"""Preset files: round trip, every kind of bad input, migration, atomic save, bundled presets, docs."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import pytest
import tomli_w
import tomllib
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app import presets
from app.params import BY_KEY, GROUPS, SPEC, Param, ParamError, Params, max_fiber_radius
from app.presets import (MIGRATIONS, PRESET_VERSION, Preset, PresetError, bundled_presets, dumps_preset,
                         find_preset, load_preset, migrate_1_to_2, parameters_markdown, save_preset)

FAST = settings(deadline=None, suppress_health_check=[HealthCheck.too_slow])


def write(tmp_path: Path, text: str | bytes, name: str = "look.toml") -> Path:
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


def error_of(path: Path) -> PresetError:
    with pytest.raises(PresetError) as info:
        load_preset(path)
    return info.value


def assert_names(e: PresetError, path: Path, line: int | None, *parts: str) -> None:
    """The message leads with file:line and contains every part (key, value, what is allowed)."""
    text = str(e)
    assert e.source == str(path)
    if line is None:
        assert text.startswith(f"{path}: "), text
    else:
        assert e.line == line, text
        assert text.startswith(f"{path}:{line}: "), text
    for part in parts:
        assert part in text, f"{part!r} not in {text!r}"


# --------------------------------------------------------------------------------------------------
# strategies built from SPEC, so a new parameter is covered without touching this file

def value_strategy(p: Param) -> st.SearchStrategy[Any]:
    if p.choices:
        return st.sampled_from(p.choices)
    if p.kind is bool:
        return st.booleans()
    if p.kind is str:
        return st.text(max_size=30)
    if p.kind is int:
        return st.integers(int(p.lo), int(p.hi))
    floats = st.floats(p.lo, p.hi, allow_nan=False, allow_infinity=False)
    return st.tuples(floats, floats, floats) if p.kind is tuple else floats


@st.composite
def valid_params(draw: st.DrawFn) -> Params:
    values = {p.key: draw(value_strategy(p)) for p in SPEC}
    # relations checked by Params: a fiber fits its ring; a groom needs a file
    values["fibers.fiber_radius"] = draw(st.floats(0.0, max_fiber_radius(values["fibers.rings"])))
    if values["scene.generator"] == "groom" and not values["scene.groom_file"]:
        values["scene.groom_file"] = "hair.ply"
    values["scene.groom_file"] = values["scene.groom_file"].replace("\0", "")  # no file name holds a NUL
    if values["camera.near"] and values["camera.far"] and values["camera.near"] >= values["camera.far"]:
        values["camera.far"] = 0.0  # near must be less than far; 0 is automatic
    return Params(values)


def exact(params: Params) -> dict[str, str]:
    # repr tells 0.1 from 0.1000000000000001, -0.0 from 0.0 and 1 from 1.0
    return {k: repr(v) for k, v in params.values.items()}


def test_round_trip_any_valid_params(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    count = 0
    path = tmp_path / "rt.toml"

    @settings(FAST, max_examples=300)
    @given(valid_params(), st.text(max_size=20), st.text(max_size=60))
    def round_trip(params: Params, name: str, description: str) -> None:
        nonlocal count
        count += 1
        save_preset(path, params, name=name, description=description)
        loaded = load_preset(path)
        assert exact(loaded.params) == exact(params)
        assert loaded.name == (name or "rt") and loaded.description == description

    round_trip()
    with capsys.disabled():
        print(f"\n[presets] round-trip count: {count} hypothesis examples saved and loaded unchanged")
    assert count >= 100
    assert [p.name for p in tmp_path.iterdir()] == ["rt.toml"]  # no temp files left behind


# --- random invalid input: whatever it is, the only exception is PresetError ----------------------

toml_scalars = st.one_of(
    st.integers(-2**63, 2**63 - 1), st.integers(), st.floats(), st.booleans(), st.text(max_size=10),
    st.dates(), st.datetimes(), st.times())
toml_values = st.recursive(
    toml_scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=8)
key_names = st.sampled_from(
    [*GROUPS, *(p.name for p in SPEC), "params", "version", "name", "description", *presets.V1_RENAMES]
) | st.text(max_size=10)
tables = st.dictionaries(key_names, toml_values, max_size=5)
documents = st.fixed_dictionaries(
    {}, optional={"version": st.sampled_from([1, 2, 3, 0, -1, 2.0, "2", True]) | toml_values}
).flatmap(lambda head: st.dictionaries(key_names, tables | toml_values, max_size=5).map(
    lambda body: {**head, **body}))
# a valid file with one line overwritten by arbitrary text (often a syntax error, sometimes not)
broken_lines = st.tuples(valid_params(), st.integers(0, 80), st.text(max_size=20))


def _broken(args: tuple[Params, int, str]) -> str:
    params, index, junk = args
    lines = dumps_preset(params).splitlines()
    lines[index % len(lines)] = junk
    return "\n".join(lines)


garbage = st.one_of(
    st.binary(max_size=200),
    st.text(max_size=200).map(lambda t: t.encode("utf-8", "surrogatepass")),
    documents.map(lambda d: tomli_w.dumps(d).encode()),
    broken_lines.map(_broken).map(str.encode),
)


def test_random_input_raises_only_preset_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    seen = {"examples": 0, "rejected": 0}
    path = tmp_path / "junk.toml"

    @settings(FAST, max_examples=400)
    @given(garbage)
    def load_junk(data: bytes) -> None:
        seen["examples"] += 1
        path.write_bytes(data)
        try:
            preset = load_preset(path)  # anything but PresetError escapes and fails the test
        except PresetError as e:
            seen["rejected"] += 1
            assert str(e).startswith(str(path)), str(e)
            assert len(str(e).splitlines()[0]) < 600  # a huge value does not flood the terminal
        else:
            assert isinstance(preset.params, Params)

    load_junk()
    with capsys.disabled():
        print(f"\n[presets] invalid-input count: {seen['examples']} examples, {seen['rejected']} "
              "rejected with PresetError, no other exception")
    assert seen["rejected"] > seen["examples"] // 2


# --- one bad value in an otherwise valid file: right key, right line, allowed values named ----------

def bad_values(p: Param) -> st.SearchStrategy[str]:
    """TOML source text of values p rejects."""
    wrong_type = ['"text"', "true", "1979-05-27", "{ a = 1 }"]
    if p.kind in (int, float):
        above = st.floats(p.hi, p.hi * 4 + 10, exclude_min=True, allow_infinity=False)
        below = st.floats(p.lo - abs(p.lo) * 4 - 10, p.lo, exclude_max=True, allow_infinity=False)
        numbers = st.one_of(above, below).map(repr)
        extra = ["nan", "inf", "-inf", "[1, 2, 3]"] + (["1.5"] if p.kind is int else [])
        return numbers | st.sampled_from(wrong_type + extra)
    if p.kind is tuple:
        return st.sampled_from(["[0.5, 0.5]", "[0.5, 0.5, 0.5, 0.5]", "[0.5, nan, 0.5]",
                                f"[0.5, {p.hi * 2 + 1!r}, 0.5]", '"red"', "0.5"])
    if p.kind is bool:
        return st.sampled_from(['"true"', "1", "0", "1.5", "[true]"])
    if p.choices:
        return st.text(min_size=1, max_size=10).filter(lambda t: t not in p.choices).map(
            lambda t: tomli_w.dumps({"v": t})[4:].strip()) | st.sampled_from(["1", "true"])
    return st.sampled_from(["1", "true", "[1, 2, 3]", "1.5"])


@st.composite
def one_bad_line(draw: st.DrawFn) -> tuple[str, Param, int, str]:
    params = draw(valid_params())
    p = draw(st.sampled_from(SPEC))
    bad = draw(bad_values(p))
    # split on newlines only: splitlines() also splits inside strings at U+2028, \x1c, \x85 ...
    lines = dumps_preset(params).split("\n")
    start = lines.index(f"[{p.group}]")
    index = next(i for i in range(start, len(lines)) if lines[i].startswith(f"{p.name} = "))
    lines[index] = f"{p.name} = {bad}"
    return "\n".join(lines), p, index + 1, bad


def test_one_bad_value_names_key_line_and_allowed(tmp_path: Path) -> None:
    path = tmp_path / "one.toml"

    @settings(FAST, max_examples=150)
    @given(one_bad_line())
    def check(case: tuple[str, Param, int, str]) -> None:
        text, p, line, bad = case
        path.write_text(text, encoding="utf-8")
        e = error_of(path)
        assert_names(e, path, line, p.key, "expected")
        assert e.key == p.key

    check()


def test_misspelled_key_suggests_the_real_one(tmp_path: Path) -> None:
    path = tmp_path / "typo.toml"

    @settings(FAST, max_examples=60)
    @given(st.sampled_from(SPEC))
    def check(p: Param) -> None:
        lines = dumps_preset(Params()).splitlines()
        start = lines.index(f"[{p.group}]")
        index = next(i for i in range(start, len(lines)) if lines[i].startswith(f"{p.name} = "))
        lines[index] = lines[index].replace(p.name, p.name + "x", 1)
        path.write_text("\n".join(lines), encoding="utf-8")
        assert_names(error_of(path), path, index + 1, f"{p.key}x", f"did you mean {p.key!r}")

    check()


# --------------------------------------------------------------------------------------------------
# every error kind, by hand

def test_syntax_error_has_line_and_column(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n[fibers]\nrings = = 3\n")
    assert_names(error_of(path), path, 3, "TOML syntax error", "column 9", "rings = = 3")


def test_number_too_long_for_python(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n[fibers]\nrings = 1" + "0" * 5000 + "\n")  # tomllib raises ValueError
    assert_names(error_of(path), path, 3, "digits")


def test_syntax_error_at_end_of_document(tmp_path: Path) -> None:
    path = write(tmp_path, 'version = 2\n[look]\ncolor = [0.1, 0.2,\n')
    assert_names(error_of(path), path, 4, "TOML syntax error", "end of document")


@pytest.mark.parametrize("text, key, line, parts", [
    ('version = 2\n[fibers]\nrings = "ten"\n', "fibers.rings", 3, ["'ten'", "an integer in [1, 64]"]),
    ("version = 2\n[fibers]\nrings = 2.5\n", "fibers.rings", 3, ["2.5", "an integer in [1, 64]"]),
    ("version = 2\n\n[fibers]\nrings = 65\n", "fibers.rings", 4, ["65", "out of range", "[1, 64]"]),
    ("version = 2\n[look]\nroughness = 0.0\n", "look.roughness", 3, ["0.0", "[0.02, 1]"]),
    ("version = 2\n[look]\nroughness = nan\n", "look.roughness", 3, ["nan", "not finite", "[0.02, 1]"]),
    ("version = 2\n[look]\nroughness = inf\n", "look.roughness", 3, ["inf", "not finite"]),
    ("version = 2\n[look]\nroughness = -inf\n", "look.roughness", 3, ["-inf", "not finite"]),
    ("version = 2\n[fibers]\nrings = inf\n", "fibers.rings", 3, ["inf", "an integer"]),
    ("version = 2\n[look]\ncolor = [1, 0]\n", "look.color", 3, ["[1, 0]", "3 numbers, each in [0, 1]"]),
    ("version = 2\n[look]\ncolor = [1, nan, 0]\n", "look.color", 3, ["nan", "3 numbers"]),
    ("version = 2\n[look]\ncolor = [1, 2, 0]\n", "look.color", 3, ["[1, 2, 0]", "out of range"]),
    ("version = 2\n[look]\nmodel = 'marshner'\n", "look.model", 3,
     ["'marshner'", "did you mean 'marschner'", "one of 'kajiya_kay', 'marschner'"]),
    ("version = 2\n[scene]\ngroom_file = 3\n", "scene.groom_file", 3, ["3", "a string"]),
    ("version = 2\n[scene]\nradius = 1" + "0" * 400 + "\n", "scene.radius", 3,
     ["out of range", "..."]),  # bigger than any float: caught, and the value is shortened
    ("version = 2\nfibers.rings = 0\n", "fibers.rings", 2, ["0", "[1, 64]"]),  # dotted key
    ("version = 2\nfibers = { seed = 1, rings = 0 }\n", "fibers.rings", 2, ["[1, 64]"]),  # inline
    ('version = 2\n[fibers]\ndescription = """\nrings = 3\n"""\nrings = 0\n', "fibers.description", 3,
     ["unknown parameter"]),  # not fooled by key-like text in a multi-line string
    ('version = 2\nname = "a\u2028b"\n[fibers]\nrings = 0\n', "fibers.rings", 4, ["[1, 64]"]),  # not a break
    ("version = 2\r\n[fibers]\r\nrings = 0\r\n", "fibers.rings", 3, ["[1, 64]"]),  # Windows line ends
])
def test_bad_values(tmp_path: Path, text: str, key: str, line: int, parts: list[str]) -> None:
    path = write(tmp_path, text)
    e = error_of(path)
    assert e.key == key
    assert_names(e, path, line, key, *parts)


def test_unknown_key_suggests_and_lists_known(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n[fibers]\nrings = 10\nphi_stepp = 2\n")
    assert_names(error_of(path), path, 4, "fibers.phi_stepp", "2", "did you mean 'fibers.phi_step'",
                 "[fibers] has: rings, phi_step")


def test_unknown_table_suggests_group(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n\n[fibres]\nrings = 10\n")
    assert_names(error_of(path), path, 3, "[fibres]", "did you mean [fibers]", "tables are: [scene]")


def test_parameter_above_its_table(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\nrings = 10\n")
    assert_names(error_of(path), path, 2, "rings = 10", "put it under [fibers]")


def test_non_table_where_table_expected(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\nfibers = 3\n")
    assert_names(error_of(path), path, 2, "fibers = 3", "should be a table", "[fibers]")


def test_array_of_tables_is_not_a_table(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n[[look]]\nroughness = 0.5\n")
    assert_names(error_of(path), path, 2, "look = [{'roughness': 0.5}]", "should be a table")


def test_missing_version(tmp_path: Path) -> None:
    path = write(tmp_path, "[fibers]\nrings = 10\n")
    assert_names(error_of(path), path, None, f"missing 'version = {PRESET_VERSION}'")


@pytest.mark.parametrize("version", ['"2"', "2.0", "true", "0", "-1", "[2]"])
def test_bad_version(tmp_path: Path, version: str) -> None:
    path = write(tmp_path, f"name = 'x'\nversion = {version}\n")
    assert_names(error_of(path), path, 2, "version = ", f"a whole number from 1 to {PRESET_VERSION}")


def test_version_from_the_future(tmp_path: Path) -> None:
    path = write(tmp_path, f"version = {PRESET_VERSION + 1}\n")
    assert_names(error_of(path), path, 1, f"version = {PRESET_VERSION + 1} is newer",
                 f"reads versions 1 to {PRESET_VERSION}", "update vfiber")


def test_name_and_description_must_be_text(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\nname = 3\n")
    assert_names(error_of(path), path, 2, "name = 3", "expected a string")


def test_not_utf8(tmp_path: Path) -> None:
    path = write(tmp_path, b"version = 2\nname = '\xff\xfe'\n")
    assert_names(error_of(path), path, 2, "not UTF-8", "byte 20")


def test_bom_is_tolerated(tmp_path: Path) -> None:
    path = write(tmp_path, "\ufeffversion = 2\n[fibers]\nrings = 12\n")
    assert load_preset(path).params["fibers.rings"] == 12


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.toml"
    assert_names(error_of(path), path, None, "cannot read the preset")


def test_directory_is_not_a_preset(tmp_path: Path) -> None:
    assert_names(error_of(tmp_path), tmp_path, None, "cannot read the preset")


def test_relation_error_gets_file_and_line(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n[fibers]\nrings = 20\nfiber_radius = 0.05\n")
    e = error_of(path)
    assert isinstance(e, ParamError) and e.key == "fibers.fiber_radius"
    assert_names(e, path, 4, "fibers.fiber_radius = 0.05", "too thick for fibers.rings = 20", "at most 0.025")


def test_groom_without_file(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n[scene]\ngenerator = 'groom'\n")
    assert_names(error_of(path), path, 2, "needs scene.groom_file")  # no such line: its table's


def test_all_problems_listed_first_by_line(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n[look]\nroughness = 5\n[fibers]\nringz = 1\nseed = -1\n")
    e = error_of(path)
    assert_names(e, path, 3, "look.roughness")
    assert f"also {path}:5: unknown parameter fibers.ringz" in str(e)
    assert f"also {path}:6: fibers.seed = -1" in str(e)


def test_nothing_is_executed(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    path = write(tmp_path, f'version = 2\n[scene]\ngroom_file = "__import__(\'os\').mkdir(\'{marker}\')"\n'
                           "generator = 'groom'\n")
    assert load_preset(path).params["scene.groom_file"].startswith("__import__")
    assert not marker.exists()


def test_missing_keys_take_defaults_and_name_defaults_to_stem(tmp_path: Path) -> None:
    path = write(tmp_path, "version = 2\n[fibers]\nrings = 12\n", name="short.toml")
    preset = load_preset(path)
    assert preset == Preset("short", "", Params({"fibers.rings": 12}), path)


# --------------------------------------------------------------------------------------------------
# migration

V1 = """version = 1
name = "Old carpet"
description = "You should see a carpet from the first format."

[params]
internal_cylinders = 8
phi_step = 2.5
phi_step_increment = 1.0
jitter = 0.3
fiber_radius = 0.05
"""


def test_every_old_version_has_a_migration() -> None:
    assert sorted(MIGRATIONS) == list(range(1, PRESET_VERSION))


def test_migrate_1_to_2_step() -> None:
    doc = migrate_1_to_2(tomllib.loads(V1))
    assert doc == {
        "version": 2, "name": "Old carpet", "description": "You should see a carpet from the first format.",
        "fibers": {"rings": 8, "phi_step": 2.5, "phi_increment": 1.0, "radial_jitter": 0.3,
                   "angular_jitter": 0.3, "fiber_radius": 0.05}}


def test_version_1_file_loads(tmp_path: Path) -> None:
    preset = load_preset(write(tmp_path, V1))
    assert preset.name == "Old carpet"
    assert preset.params == Params({"fibers.rings": 8, "fibers.phi_step": 2.5, "fibers.phi_increment": 1.0,
                                    "fibers.radial_jitter": 0.3, "fibers.angular_jitter": 0.3,
                                    "fibers.fiber_radius": 0.05})


def test_version_1_errors_point_at_old_keys(tmp_path: Path) -> None:
    path = write(tmp_path, V1.replace("jitter = 0.3", "jitter = 3"))
    assert_names(error_of(path), path, 9, "fibers.radial_jitter = 3", "from params.jitter",
                 "version-1 preset", "[0, 1]")
    path = write(tmp_path, V1.replace("internal_cylinders", "internal_cylinder"))
    assert_names(error_of(path), path, 6, "params.internal_cylinder", "did you mean 'internal_cylinders'")
    path = write(tmp_path, "version = 1\nparams = 4\n")
    assert_names(error_of(path), path, 2, "should be a table")
    path = write(tmp_path, "version = 1\n[fibers]\nrings = 4\n")
    assert_names(error_of(path), path, 2, "unknown top-level key 'fibers'", "version-1 preset")


def test_migrated_preset_saves_as_current_version(tmp_path: Path) -> None:
    old = load_preset(write(tmp_path, V1))
    new = save_preset(tmp_path / "new.toml", old.params, old.name, old.description)
    assert tomllib.loads(new.read_text())["version"] == PRESET_VERSION
    assert load_preset(new).params == old.params


# --------------------------------------------------------------------------------------------------
# saving

def test_saved_file_lists_every_parameter_in_spec_order(tmp_path: Path) -> None:
    path = save_preset(tmp_path / "all.toml", Params(), name="Defaults", description="You should see...")
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    assert list(doc) == ["version", "name", "description", *GROUPS]
    flat = [f"{g}.{n}" for g in GROUPS for n in doc[g]]
    assert flat == [p.key for p in SPEC]
    assert "color = [0.55, 0.36, 0.2]" in path.read_text()  # colours on one line
    assert "seed = 1  # an integer in [0, 2147483647]" in path.read_text()


def test_save_rejects_non_params(tmp_path: Path) -> None:
    with pytest.raises(TypeError):
        save_preset(tmp_path / "x.toml", {"fibers.rings": 3})  # type: ignore[arg-type]


@pytest.mark.parametrize("victim", ["replace", "fsync"])
def test_atomic_save_keeps_old_file_on_failure(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               victim: str) -> None:
    path = save_preset(tmp_path / "look.toml", Params({"fibers.rings": 5}), name="old")
    before = path.read_bytes()

    def boom(*args: Any, **kwargs: Any) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, victim, boom)
    with pytest.raises(OSError, match="No space left"):
        save_preset(path, Params({"fibers.rings": 6}), name="new")
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["look.toml"]  # temp file removed
    assert load_preset(path).params["fibers.rings"] == 5


def test_atomic_save_survives_interrupt_in_writer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = save_preset(tmp_path / "look.toml", Params(), name="old")
    before = path.read_bytes()
    real_write_text = Path.write_text

    def half_write(self: Path, text: str, *args: Any, **kwargs: Any) -> int:
        real_write_text(self, text[:50], *args, **kwargs)
        raise KeyboardInterrupt  # Ctrl-C halfway through the write

    monkeypatch.setattr(Path, "write_text", half_write)
    with pytest.raises(KeyboardInterrupt):
        save_preset(path, Params({"fibers.rings": 6}))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["look.toml"]


def test_save_replaces_and_keeps_mode(tmp_path: Path) -> None:
    path = save_preset(tmp_path / "look.toml", Params())
    os.chmod(path, 0o640)
    save_preset(path, Params({"fibers.rings": 7}))
    assert load_preset(path).params["fibers.rings"] == 7
    if os.name == "posix":
        assert path.stat().st_mode & 0o777 == 0o640


# --------------------------------------------------------------------------------------------------
# bundled presets and lookup

def test_bundled_presets_load_if_present() -> None:
    # presets/ is filled by someone else; every file there must load and say what you should see
    for preset in bundled_presets():
        assert preset.path is not None and preset.path.suffix == ".toml"
        assert preset.description, f"{preset.path}: add description = \"You should see ...\""


def test_find_preset_by_path_and_name(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "bundled"
    folder.mkdir()
    save_preset(folder / "blonde.toml", Params({"look.melanin": 0.1}), description="You should see blonde")
    save_preset(folder / "dark.toml", Params({"look.melanin": 0.9}), description="You should see dark")
    monkeypatch.setattr(presets, "presets_dir", lambda: folder)
    assert [p.name for p in bundled_presets()] == ["blonde", "dark"]
    assert find_preset("dark").params["look.melanin"] == 0.9
    assert find_preset("dark.toml").params["look.melanin"] == 0.9
    own = save_preset(tmp_path / "mine.toml", Params({"fibers.rings": 3}))
    assert find_preset(own).params["fibers.rings"] == 3
    assert find_preset(str(own)).path == own
    with pytest.raises(PresetError) as info:
        find_preset("blond")
    assert "did you mean 'blonde'" in str(info.value)
    assert "bundled presets: blonde, dark" in str(info.value)


def test_presets_dir_falls_back_to_checkout() -> None:
    folder = presets.presets_dir()
    assert folder is None or folder.is_dir()


# --------------------------------------------------------------------------------------------------
# docs/parameters.md

def test_parameters_doc_is_up_to_date() -> None:
    expected = parameters_markdown()
    actual = presets.DOCS_PATH.read_text(encoding="utf-8") if presets.DOCS_PATH.exists() else ""
    assert actual == expected, (f"{presets.DOCS_PATH} is out of date with app/params.py; regenerate it "
                                "with: python -m app.presets --docs")


def test_parameters_doc_covers_every_key() -> None:
    text = parameters_markdown()
    for p in SPEC:
        row = next(line for line in text.splitlines() if line.startswith(f"| `{p.key}` |"))
        assert p.help.split()[0] in row
        if p.choices:
            assert all(f"`{c}`" in row for c in p.choices)
    assert "2147483647" in text  # integer bounds printed exactly


def test_cli_check(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(presets, "DOCS_PATH", tmp_path / "parameters.md")
    assert presets.main(["--check"]) == 1
    assert presets.main(["--docs"]) == 0
    assert presets.main(["--check"]) == 0
    good = save_preset(tmp_path / "good.toml", Params())
    bad = write(tmp_path, "version = 2\n[fibers]\nrings = 0\n", name="bad.toml")
    assert presets.main([str(good), str(bad)]) == 1
    assert f"{bad}:3:" in capsys.readouterr().err


def test_values_are_finite_after_load(tmp_path: Path) -> None:
    # belt and braces for the renderer: nothing non-finite slips through via a tuple or an int
    preset = load_preset(save_preset(tmp_path / "d.toml", Params()))
    for key, value in preset.params.values.items():
        for v in value if isinstance(value, tuple) else (value,):
            if isinstance(v, float):
                assert math.isfinite(v), key
    assert set(preset.params.values) == set(BY_KEY)


# --------------------------------------------------------------------------------------------------
# a preset's look on a groom (issue 15): only the look groups travel, the groom keeps its shot

SINTEL = Path(__file__).resolve().parents[1].parent / "shared" / "hair-data" / "sintel_hair.tfx"
needs_sintel = pytest.mark.skipif(not SINTEL.exists(), reason=f"{SINTEL} not present")


def as_sets(values: dict[str, Any]) -> list[str]:
    """``--set`` texts that give these values, written as a person would type them."""
    def text(v: Any) -> str:
        if isinstance(v, tuple):
            return ",".join(repr(float(x)) for x in v)
        return str(v).lower() if isinstance(v, bool) else repr(v) if isinstance(v, float) else str(v)
    return [f"{k}={text(v)}" for k, v in values.items()]


def test_the_look_and_the_shot_split_every_group_once():
    """A parameter group nobody placed would travel with no preset or with every one: name it in one list."""
    unplaced = set(GROUPS) - set(presets.LOOK_GROUPS) - set(presets.SHOT_GROUPS)
    assert not unplaced, f"put {sorted(unplaced)} in presets.LOOK_GROUPS or presets.SHOT_GROUPS"
    assert not set(presets.LOOK_GROUPS) & set(presets.SHOT_GROUPS)
    assert set(presets.LOOK_GROUPS) | set(presets.SHOT_GROUPS) == set(GROUPS)   # and no group that is gone
    assert {"scene", "camera"} <= set(presets.SHOT_GROUPS)


@needs_sintel
@pytest.mark.parametrize("name", [p.path.stem for p in bundled_presets() if p.params["scene.generator"] != "groom"])
def test_a_look_on_a_groom_takes_the_presets_look_and_keeps_the_grooms_shot(name):
    groom, _ = presets.resolve_params(str(SINTEL))
    looked, label = presets.resolve_params(str(SINTEL), look=name)
    look = find_preset(name).params
    for key in groom:
        want = look[key] if key.split(".", 1)[0] in presets.LOOK_GROUPS else groom[key]
        assert looked[key] == want, key
    assert label.startswith(str(SINTEL)) and name in label
    # the same as typing the preset's look values with --set: nothing else is carried
    changed = {k: v for k, v in presets.look_values(look).items() if v != groom[k]}
    assert presets.resolve_params(str(SINTEL), as_sets(changed))[0] == looked


@needs_sintel
def test_set_goes_on_top_of_the_look_and_the_order_of_target_and_look_does_not_matter():
    p, _ = presets.resolve_params(str(SINTEL), ["shape.curl_frequency=2", "scene.groom_cluster=10"], look="curly-1")
    assert p["shape.curl_frequency"] == 2 and p["shape.curl_amplitude"] == 0.5 and p["scene.groom_cluster"] == 10
    # --preset alone (or equal to the target) is the target itself, as before
    assert presets.resolve_params(None, look="curly-1")[0] == presets.resolve_params("curly-1")[0]
    assert presets.resolve_params("curly-1", look="curly-1")[0] == presets.resolve_params("curly-1")[0]


@needs_sintel
def test_a_preset_holding_a_groom_is_a_groom_target_too(tmp_path):
    held = write(tmp_path, f'version = 2\n[scene]\ngenerator = "groom"\ngroom_file = {str(SINTEL)!r}\n'
                           '[camera]\nazimuth = 75.0\n', "sintel.toml")
    p, _ = presets.resolve_params(str(held), look="fur-ball")
    assert p["look.model"] == "marschner" and p["camera.azimuth"] == 75.0
    assert p["scene.groom_file"] == str(SINTEL)


@needs_sintel
def test_a_look_that_cannot_go_on_a_groom_says_why(tmp_path):
    from app.errors import UsageError

    with pytest.raises(PresetError, match="no bundled preset of that name.*did you mean 'curly-"):
        presets.resolve_params(str(SINTEL), look="curly-9")
    with pytest.raises(UsageError, match="two grooms given.*--preset takes a look"):
        presets.resolve_params(str(SINTEL), look=str(SINTEL.with_name("Bangs_100.hair")))
    groom_preset = write(tmp_path, f'version = 2\n[scene]\ngenerator = "groom"\ngroom_file = {str(SINTEL)!r}\n')
    with pytest.raises(UsageError, match=r"is itself a groom \(scene.groom_file = .*sintel_hair.tfx"):
        presets.resolve_params(str(SINTEL), look=str(groom_preset))
    with pytest.raises(UsageError, match="two scenes given: 'default' and --preset 'curly-1'.*groom"):
        presets.resolve_params("default", look="curly-1")
