"""The option schema (addon/atlas_defrag/options.py) against the places it
feeds that run without Blender: the native module's own range checks, the
batch entry's arguments and the README's table."""
import numpy as np
import pytest

from atlas_defrag import batch, job, options


def tiny():
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    triangles = np.array([[0, 1, 2], [1, 3, 2]], np.int32)
    uvs = positions[triangles][:, :, :2] * 0.5
    return positions, triangles, uvs, np.zeros(2, np.int32), np.array([[64, 64]], np.int32)


def probes(option):
    """Values on both sides of every bound, and 0 where it means automatic."""
    if option.choices:
        return [c.value for c in option.choices] + ["area"]
    if option.kind is bool:
        return [True, False, "yes"]
    step = 1 if option.kind is int else option.low / 2 or 0.5
    values = [option.low, option.low - step] + ([0, -step] if option.automatic else [])
    if option.high is not None:
        values += [option.high, option.high + step]
    return list(dict.fromkeys(values))


def with_room(name, value):
    """The option alone, and max_page_size at its largest so that
    fixed_page_size meets only its own bounds."""
    values = {name: value}
    if name == "fixed_page_size":
        values["max_page_size"] = options.BY_NAME["max_page_size"].high
    return values


def native_accepts(native, values) -> bool:
    if options.BY_NAME[next(iter(values))].job:  # job.run's own: the native module never sees it
        return python_accepts(values)
    if options.BY_NAME[next(iter(values))].bake:
        return bake_accepts(native, values)
    # A cancelled token stops the run right after the options are read.
    token = native.CancelToken()
    token.cancel()
    try:
        native.defragment(*tiny(), options=values, cancel=token)
    except native.Cancelled:
        return True
    except ValueError as exc:
        assert next(iter(values)) in str(exc), exc  # the message names the option
        return False
    raise AssertionError("a cancelled run returned")


def bake_accepts(native, values) -> bool:
    """The bake's options are keywords of bake_maps: a wrong type is a TypeError."""
    positions, triangles, uvs, face_page, page_sizes = tiny()
    image = np.zeros((64, 64, 3), np.uint8)
    try:
        native.bake_maps(uvs, face_page, [[image]], uvs, face_page, [(64, 64)], **values)
    except TypeError:
        return False
    return True


def python_accepts(values) -> bool:
    try:
        job.Options(**values).validate()
    except job.DefragError as exc:
        assert next(iter(values)) in str(exc), exc
        return False
    return True


CASES = [(o.name, v) for o in options.SCHEMA for v in probes(o)]


@pytest.mark.parametrize("name, value", CASES, ids=[f"{n}={v}" for n, v in CASES])
def test_native_module_checks_the_same_ranges(native, name, value):
    values = with_room(name, value)
    assert native_accepts(native, values) == python_accepts(values)


def test_the_probes_reach_both_sides_of_every_bound():
    for o in options.SCHEMA:
        verdicts = {python_accepts(with_room(o.name, v)) for v in probes(o)}
        assert verdicts == {True, False}, o.name


def test_a_fixed_page_larger_than_the_largest_page_is_refused_on_both_sides(native):
    values = {"fixed_page_size": 4096, "max_page_size": 2048}
    assert not native_accepts(native, values) and not python_accepts(values)


@pytest.mark.parametrize("fixed, sides, accepted", [
    (1000, "power_of_two", False), (1024, "power_of_two", True), (1001, "multiple_of_4", False),
    (1000, "multiple_of_4", True), (1001, "tight", True),
])
def test_a_fixed_page_of_another_kind_than_page_sides_is_refused_on_both_sides(native, fixed, sides, accepted):
    """A fixed page side that page_sides does not allow was used as given."""
    values = {"fixed_page_size": fixed, "page_sides": sides}
    assert native_accepts(native, values) == accepted and python_accepts(values) == accepted


def test_every_option_reaches_the_native_module(native):
    """The native module knows every name (it refuses unknown ones): the
    layout's in defragment, the bake's in bake_maps."""
    chosen = job.Options()
    assert native_accepts(native, chosen.native())
    job_own = {o.name for o in options.SCHEMA if o.job}
    assert set(chosen.native()) | set(chosen.bake()) | job_own == set(options.BY_NAME)
    assert bake_accepts(native, chosen.bake())


def test_batch_arguments_follow_the_schema(capsys):
    parser = batch.single_parser()
    args = parser.parse_args(["in.obj", "out.glb"])
    assert {o.name: getattr(args, o.name) for o in options.SCHEMA} == job.Options().values()
    args = parser.parse_args(["in.obj", "out.glb", "--fixed-page-size", "1024", "--weighting", "uv"])
    assert (args.fixed_page_size, args.weighting) == (1024, "uv")
    with pytest.raises(SystemExit) as exc:
        parser.parse_args(["in.obj", "out.glb", "--padding", "65"])
    assert exc.value.code == 2 and "padding must be 0..64" in capsys.readouterr().err


def test_readme_option_table_is_current():
    import options_doc

    text = options_doc.README.read_text()
    assert options_doc.update(text) == text, "run tools/options_doc.py"


def test_argument_words_parse_back_to_the_value():
    """What the many-models form passes on to each single-model run."""
    parser = batch.single_parser()
    for o in options.SCHEMA:
        for value in probes(o):
            try:
                value = options.check(o, value)
            except ValueError:
                continue
            args = parser.parse_args(["in.obj", "out.glb"] + options.argument_words(o, value))
            assert getattr(args, o.name) == value, (o.name, value)


def test_the_info_line_says_when_charts_were_cut_to_fit():
    report = {"charts_before": 159, "charts_after": 46, "seam_before": 26.2, "seam_after": 13.9, "pages_before": 1,
              "pages_after": 1, "padding": 2, "packing_cuts": 24, "seconds": {"total": 1.0}}
    assert "stay within" not in job.summary(report)
    assert "24 cuts for packing to stay within the source's texels" in job.summary({**report, "cut_to_fit": True})


def test_infinities_and_numpy_scalars_get_the_options_words():
    """An infinity for an integer option is refused as any value out of
    range (it raised OverflowError); numpy scalars count as the Python values
    they hold, so a numpy bool is a bool and a float32 is judged at its real value."""
    by_name = options.BY_NAME
    for name in ("target_charts", "padding", "max_pages"):
        for value in (float("inf"), float("-inf")):
            with pytest.raises(ValueError, match=f"{name} must be"):
                options.check(by_name[name], value)
    assert options.check(by_name["padding_follows_page"], np.bool_(False)) is False
    assert options.check(by_name["padding"], np.int64(8)) == 8
    assert options.check(by_name["density_scale"], np.float32(0.5)) == 0.5
    with pytest.raises(ValueError, match="not 0.800000011920929"):
        options.check(by_name["density_loss_budget"], np.float32(0.8))
