"""The backend vocabulary (scdk_sym.backends): every name, aliases, refusals, CLI help."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from factories import MODELS, SEED_THETA0, compiler_missing, shipped

import scdk_sym as sc
from scdk_sym import backends, cli
from scdk_sym.algebraic import algebraic_form
from scdk_sym.errors import InputError
from scdk_sym.follower.calls import follower_kernels
from scdk_sym.follower.cvodes import engine
from scdk_sym.solvers.modes import explore

#: Every public entry point with a backend argument -> (registry key, a call with ``backend``).
ENTRY_POINTS = {
    "solve": lambda b: sc.solve(shipped("planar_hexa"), SEED_THETA0, backend=b),
    "track": lambda b: sc.track(shipped("planar_hexa"), [SEED_THETA0], backend=b),
    "modes": lambda b: sc.assembly_modes(shipped("planar_3rpr"), [0.4, 0.5, 0.4], backend=b),
    "curves": lambda b: explore(shipped("planar_3rpr"), [0.4, 0.5, 0.4], backend=b),
    "kernels": lambda b: follower_kernels(shipped("planar_hexa"), b),
}


@pytest.fixture
def fresh_warnings(monkeypatch):
    """Forget which aliases already warned in this process."""
    monkeypatch.setattr(backends, "_WARNED", set())


def test_every_name_is_defined_once_with_a_one_line_help():
    assert set(backends.BACKENDS) == {"auto", "cvodes", "compiled", "c"}
    for name, b in backends.BACKENDS.items():
        assert b.name == name and b.help and "\n" not in b.help and len(b.help) < 120
    assert not set(backends.ALIASES) & set(backends.BACKENDS)
    assert set(backends.ALIASES.values()) <= set(backends.BACKENDS)
    for function, names in backends.OFFERS.items():
        assert names and set(names) <= set(backends.BACKENDS) - {"auto"}, function
        assert backends.offered(function) == ("auto", *names)
        assert backends.DEFAULTS[function] in backends.offered(function)
    # the public contract names of DESIGN.md section 5
    assert backends.OFFERS["track"] == ("c", "cvodes")
    assert backends.DEFAULTS == {
        "solve": "cvodes",
        "track": "cvodes",
        "modes": "auto",
        "curves": "cvodes",
        "kernels": "cvodes",
    }


@pytest.mark.parametrize("function", sorted(backends.OFFERS))
def test_resolve_keeps_every_offered_name_and_refuses_the_others(function):
    for name in backends.OFFERS[function]:
        assert backends.resolve(name, function) == name
    for name in set(backends.BACKENDS) - set(backends.offered(function)):
        with pytest.raises(InputError) as info:
            backends.resolve(name, function)
        message = str(info.value)
        assert f"{name!r} is not offered by {function}" in message
        assert f"backends: {', '.join(backends.offered(function))}" in message


@pytest.mark.parametrize("function", sorted(ENTRY_POINTS))
def test_every_entry_point_refuses_an_unknown_name_listing_its_names(function):
    with pytest.raises(InputError) as info:
        ENTRY_POINTS[function]("gpu")
    assert str(info.value).startswith(f"backend 'gpu' is not offered by {function}; backends: ")
    assert str(info.value).count(",") == len(backends.OFFERS[function])


def test_entry_points_refuse_names_of_other_functions():
    with pytest.raises(InputError, match="'c' is not offered by modes; backends: auto, compiled"):
        sc.assembly_modes(shipped("planar_3rpr"), [0.4, 0.5, 0.4], backend="c")
    with pytest.raises(InputError, match="'compiled' is not offered by track; backends: auto, c"):
        sc.track(shipped("planar_hexa"), [SEED_THETA0], backend="compiled")
    with pytest.raises(InputError, match="'c' is not offered by kernels"):
        algebraic_form(shipped("five_bar"), "c")


def test_auto_takes_the_fastest_available(monkeypatch):
    for function, names in backends.OFFERS.items():
        expect = names[0] if compiler_missing() is None else names[-1]
        assert backends.resolve("auto", function) == expect, function
    monkeypatch.setenv("CC", "/nonexistent/cc")  # no usable compiler
    for function, names in backends.OFFERS.items():
        assert backends.resolve("auto", function) == "cvodes" == names[-1], function


def test_alias_warns_once_and_means_the_same(fresh_warnings):
    with pytest.warns(DeprecationWarning, match="'casadi' is deprecated; use 'cvodes'"):
        assert backends.resolve("casadi", "solve") == "cvodes"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a second warning would raise
        assert backends.resolve("casadi", "curves") == "cvodes"
        assert backends.resolve("casadi", "kernels") == "cvodes"
        assert backends.resolve("casadi", "track") == "cvodes"  # one meaning everywhere


def test_alias_keeps_old_calls_working_with_the_same_results(fresh_warnings):
    model = shipped("planar_hexa")
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    with pytest.warns(DeprecationWarning):
        old = sc.solve(model, SEED_THETA0, start=start, branch="divergent", backend="casadi")
    new = sc.solve(model, SEED_THETA0, start=start, branch="divergent", backend="cvodes")
    default = sc.solve(model, SEED_THETA0, start=start, branch="divergent")
    # the paper's divergent solution phi = 0.9999 (section 5), identical for the three names
    assert abs(new.x[2] - 0.9999) < 1e-3
    np.testing.assert_array_equal(old.x, new.x)
    np.testing.assert_array_equal(default.x, new.x)
    # the kernel caches hold one entry per backend, whatever name asked for it
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        assert follower_kernels(model, "casadi") is follower_kernels(model, "cvodes")
        assert engine(model, "casadi") is engine(model, "cvodes")


def test_every_backend_option_shares_the_registry_help():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    seen = {}
    for name, p in sub.choices.items():
        for action in p._actions:
            if action.dest == "backend":
                seen[name] = action
    assert set(seen) == {"solve", "modes", "track"}
    for command, action in seen.items():
        for b in backends.offered(command):
            assert f"{b}: {backends.BACKENDS[b].help}" in action.help, (command, b)
        assert "casadi: deprecated name of cvodes" in action.help
        assert action.choices is None  # validated by the registry, not by argparse
    assert seen["solve"].default == seen["track"].default == "cvodes"
    assert seen["modes"].default is None  # homotopy: auto, curves: cvodes (assembly_modes)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["solve", "--theta", "1,2,3", "--backend", "gpu"], "not offered by solve; backends: auto"),
        (["track", "--thetas", "none.csv", "--backend", "compiled"], "not offered by track"),
        (["modes", "--theta", "1,2,3", "--backend", "c"], "not offered by modes"),
        (["modes", "--theta", "1,2,3", "--method", "curves", "--backend", "c"], "by curves"),
    ],
)
def test_cli_refuses_before_any_work(capsys, argv, message):
    argv = [argv[0], str(MODELS / "no_such_model"), *argv[1:]]  # never loaded
    assert cli.main(argv) == 1
    err = capsys.readouterr().err
    assert message in err and "no_such_model" not in err


def test_cli_notes_the_deprecated_name(capsys, fresh_warnings):
    theta = ",".join(repr(float(v)) for v in SEED_THETA0)
    argv = ["solve", str(MODELS / "planar_hexa"), "--theta", theta, "--from-x", "0,0,0.4"]
    assert cli.main([*argv, "--backend", "casadi"]) == 0
    out, err = capsys.readouterr()
    assert "note: --backend casadi is deprecated; use --backend cvodes" in err
    assert cli.main(argv) == 0
    assert capsys.readouterr().out == out  # the same solution as the default


@pytest.mark.parametrize("function", ["solve", "track", "modes", "curves"])
@pytest.mark.parametrize("name", ["auto", "cvodes"])
def test_a_public_call_resolves_its_backend_once_and_passes_the_choice_down(
    monkeypatch, function, name
):
    """The layers under a public function (the follower, its kernels, the algebraic form)
    take the resolved choice as it is: one validation per call, and ``auto`` chosen once."""
    ENTRY_POINTS[function]("cvodes")  # build what the call needs once, outside the count
    calls: list[tuple[str, str]] = []
    canonical = backends.canonical

    def counted(backend, fn):
        calls.append((backend, fn))
        return canonical(backend, fn)

    monkeypatch.setattr(backends, "canonical", counted)
    ENTRY_POINTS[function](name)
    assert calls == [(name, function)]


def test_a_resolved_choice_stays_itself_below_and_is_checked_against_another_function():
    import pickle

    choice = backends.resolve("cvodes", "solve")
    assert isinstance(choice, backends.Resolved) and choice == "cvodes"
    assert choice.asked == "cvodes" and backends.resolve(choice, "kernels") is choice
    copy = pickle.loads(pickle.dumps(choice))
    assert copy == "cvodes" and isinstance(copy, backends.Resolved)
    c = backends.Resolved("c", "auto")  # the C follower: solve's and track's, not the kernels'
    with pytest.raises(InputError, match="backend 'c' is not offered by kernels"):
        backends.resolve(c, "kernels")
