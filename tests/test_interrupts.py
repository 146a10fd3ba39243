"""SIGINT/SIGTERM inside :func:`stop_on_signals`: the stop is raised, also when a library
turned it into its own error on the way out (CasADi reports an interrupt during argument
conversion as a ``NotImplementedError``), and a real error stays itself."""

from __future__ import annotations

import os
import signal
import sys

import pytest

from scdk_sym.errors import Interrupted
from scdk_sym.interrupts import check, on_stop, requested, stop_for, stop_on_signals


def _library_call_interrupted_by(sig: signal.Signals) -> None:
    """What a wrapped library does: it catches the raise and reports its own error."""
    try:
        os.kill(os.getpid(), sig)  # the handler runs before os.kill returns
        raise AssertionError("the signal handler did not raise")
    except BaseException as exc:
        raise NotImplementedError("Wrong number or type of arguments") from exc


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_error_a_library_made_of_a_signal_leaves_the_block_as_the_stop(sig):
    before = signal.getsignal(signal.SIGINT)  # SIG_IGN when the run started in the background
    with pytest.raises(Interrupted) as info, stop_on_signals():
        _library_call_interrupted_by(sig)
    assert info.value.signal == sig.name
    assert isinstance(info.value.__cause__, NotImplementedError)
    assert requested() is None  # cleared once the outermost block is left
    assert signal.getsignal(signal.SIGINT) is before  # the handler in place before the block


def test_nested_blocks_convert_at_the_inner_one_and_a_real_error_stays_itself():
    with stop_on_signals():
        with pytest.raises(Interrupted) as info, stop_on_signals():
            _library_call_interrupted_by(signal.SIGINT)
        assert requested() == "SIGINT"  # still inside the outer block: check() stops too
        with pytest.raises(Interrupted):
            check()
    assert stop_for(ValueError("a real error")) is None  # no stop requested any more
    assert stop_for(info.value) is info.value
    with pytest.raises(ValueError, match="a real error"), stop_on_signals():
        raise ValueError("a real error")


def test_casadi_s_report_of_the_interrupt_is_not_printed_but_other_lines_are(capsys):
    """A CVODES integration stopped by a real SIGINT: CasADi's ``rhs failed:
    KeyboardInterrupt`` line is dropped from stderr; a line written after it, and every line
    written before the signal, are kept."""
    import threading

    import casadi as ca

    x, z = ca.MX.sym("x", 50), ca.SX.sym("z", 50)  # an oscillator, through a Function call
    rhs = ca.Function("rhs", [z], [ca.vertcat(z[25:], -z[:25]) * (1 + 0.1 * ca.sin(ca.sum1(z)))])
    grid = [50.0 * i for i in range(1, 200000)]  # minutes of integration: the signal ends it
    opts = {"max_num_steps": 10**7, "abstol": 1e-14, "reltol": 1e-13}
    F = ca.integrator("F", "cvodes", {"x": x, "ode": rhs(x)}, 0.0, grid, opts)
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    with pytest.raises(Interrupted), stop_on_signals():
        print("before the signal", file=sys.stderr)
        timer.start()
        try:
            F(x0=1.0)
        except RuntimeError:  # CasADi's report of the stop: check() names it
            print("after it", file=sys.stderr)
            check()
        raise AssertionError("the integration was not interrupted")
    timer.join()
    err = capsys.readouterr().err
    assert "failed:" not in err and "KeyboardInterrupt" not in err, err
    assert "before the signal\n" in err and "after it\n" in err, err


def test_a_stop_hook_runs_in_the_handler_before_the_raise_and_only_within_its_block():
    seen: list[str | None] = []
    with pytest.raises(Interrupted), stop_on_signals(), on_stop(lambda: seen.append(requested())):
        os.kill(os.getpid(), signal.SIGTERM)
        seen.append("after the raise")  # never reached
    assert seen == ["SIGTERM"]
    with pytest.raises(Interrupted), stop_on_signals():
        with on_stop(lambda: seen.append("inner")):
            pass
        os.kill(os.getpid(), signal.SIGINT)
    assert seen == ["SIGTERM"]
