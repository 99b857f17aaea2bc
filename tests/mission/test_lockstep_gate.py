"""The lockstep gate without ROS: command validation (NaN/inf, wrong joints, frames, stale/future stamps,
clamping), the lockstep handshake and start-up settle, the watchdog's re-send and timeout, and the real-time
failsafe engaging and releasing.  The simulator node and the replayer both call this code."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bb2_mission.lockstep_gate import (CommandLimits, CommandValidator, Counter, GateTimings, LockstepGate,
                                       TimeMode, WatchdogAction)

PLANES = ("delta1", "delta2", "delta3", "delta4", "delta5")
PROP = "propeller"
FRAME = "base_link"
NS = 1_000_000_000
LIMITS = CommandLimits(PLANES, PROP, FRAME, plane_limit_deg=30.0, rps_limits=(-10.0, 10.0))


def planes_rad(*deg):
    return [math.radians(d) for d in deg]


def gate(mode=TimeMode.LOCKSTEP, **timings):
    t = dict(lockstep_timeout_s=1.0, lockstep_retry_s=0.1, startup_timeout_s=30.0, startup_settle_s=0.0,
             command_timeout_s=0.5)
    t.update(timings)
    return LockstepGate(CommandValidator(LIMITS, mode=mode, max_command_age_s=1.0, step_s=0.05),
                        GateTimings(**t), nominal_rps=1.25)


# ------------------------------------------------------------------------------------------ validation
def test_planes_in_any_joint_order_come_out_in_rom_order_in_degrees():
    v = CommandValidator(LIMITS).planes(list(reversed(PLANES)), planes_rad(5, 4, 3, 2, 1), FRAME, 0, 0)
    assert v.accepted and v.counter is None and not v.message
    np.testing.assert_allclose(v.value, [1, 2, 3, 4, 5], rtol=0, atol=1e-12)


@pytest.mark.parametrize("names,values", [
    (PLANES[:4], planes_rad(1, 2, 3, 4)),                                      # one joint missing
    (PLANES[:4] + ("delta1",), planes_rad(1, 2, 3, 4, 5)),                     # a joint twice
    (PLANES[:4] + ("rudder",), planes_rad(1, 2, 3, 4, 5)),                     # an unknown joint
    (PLANES, planes_rad(1, 2, 3, 4)),                                          # names and values differ in size
])
def test_wrong_plane_joints_are_rejected(names, values):
    v = CommandValidator(LIMITS).planes(names, values, FRAME, 0, 0)
    assert not v.accepted and v.counter is Counter.REJECTED_NAMES and "expected the 5 joints" in v.message


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_commands_are_rejected_never_integrated(bad):
    val = CommandValidator(LIMITS)
    v = val.planes(PLANES, [0.0, 0.0, bad, 0.0, 0.0], FRAME, 0, 0)
    assert v.value is None and v.counter is Counter.REJECTED_NONFINITE and "never integrated" in v.message
    v = val.propeller([PROP], [bad], FRAME, 0, 0)
    assert v.value is None and v.counter is Counter.REJECTED_NONFINITE


def test_wrong_propeller_joint_and_frame_are_rejected():
    val = CommandValidator(LIMITS)
    assert val.propeller(["shaft"], [1.0], FRAME, 0, 0).counter is Counter.REJECTED_NAMES
    assert val.propeller([PROP, PROP], [1.0, 1.0], FRAME, 0, 0).counter is Counter.REJECTED_NAMES
    v = val.planes(PLANES, planes_rad(0, 0, 0, 0, 0), "odom", 0, 0)
    assert v.counter is Counter.REJECTED_FRAME and "'odom'" in v.message


def test_commands_beyond_the_rom_limits_are_clamped():
    val = CommandValidator(LIMITS)
    v = val.planes(PLANES, planes_rad(45, -45, 10, 0, 0), FRAME, 0, 0)
    assert v.accepted and v.clamped and v.counter is Counter.CLAMPED
    np.testing.assert_allclose(v.value, [30, -30, 10, 0, 0], atol=1e-12)
    v = val.propeller([PROP], [2 * math.pi * 12.0], FRAME, 0, 0)
    assert v.value == 10.0 and v.counter is Counter.CLAMPED
    assert val.propeller([PROP], [2 * math.pi * 3.0], FRAME, 0, 0).value == pytest.approx(3.0, abs=1e-15)


def test_lockstep_stamps_must_equal_the_step():
    val = CommandValidator(LIMITS, mode=TimeMode.LOCKSTEP)
    now = 7 * NS
    assert val.propeller([PROP], [1.0], FRAME, now, now).accepted
    late = val.propeller([PROP], [1.0], FRAME, now - 1, now)
    assert late.counter is Counter.LATE_COMMANDS and not late.message  # an answer to an earlier step: quiet
    assert val.propeller([PROP], [1.0], FRAME, now + 1, now).counter is Counter.REJECTED_FUTURE


def test_realtime_stamps_stale_beyond_max_age_or_ahead_beyond_one_step():
    val = CommandValidator(LIMITS, mode=TimeMode.REALTIME, max_command_age_s=1.0, step_s=0.05)
    now = 10 * NS
    assert val.propeller([PROP], [1.0], FRAME, now - NS, now).accepted          # exactly max age: kept
    assert val.propeller([PROP], [1.0], FRAME, now - NS - 1, now).counter is Counter.REJECTED_STALE
    assert val.propeller([PROP], [1.0], FRAME, now + NS // 20, now).accepted     # one step ahead: kept
    assert val.propeller([PROP], [1.0], FRAME, now + NS // 20 + 1, now).counter is Counter.REJECTED_FUTURE


def test_no_stamp_check_for_recorded_commands():
    v = CommandValidator(LIMITS, mode=TimeMode.REALTIME).propeller([PROP], [1.0], FRAME)
    assert v.accepted


# ------------------------------------------------------------------------------------------ lockstep
def test_lockstep_steps_only_with_both_answers_of_the_step():
    g = gate()
    g.state_sent(0.0)
    g.on_planes(PLANES, planes_rad(1, 1, 1, 1, 1), FRAME, 0, 0, 0.01)
    assert g.answer(0, 0.01) is None                      # propeller still missing
    g.on_propeller([PROP], [2 * math.pi], FRAME, 0, 0, 0.02)
    d = g.answer(0, 0.02)
    assert d is not None and not d.failsafe and d.rps == pytest.approx(1.0)
    np.testing.assert_allclose(d.planes_deg, [1] * 5, atol=1e-12)
    g.stepped()
    assert g.answer(1, 0.03) is None                      # the next step starts with no answers


def test_rejected_or_late_answers_never_complete_a_step():
    g = gate()
    now = 3 * NS
    g.on_planes(PLANES, planes_rad(1, 1, 1, 1, 1), FRAME, now - NS, now, 0.0)       # late
    g.on_planes(PLANES, [math.nan] * 5, FRAME, now, now, 0.0)                        # non-finite
    g.on_propeller([PROP], [1.0], FRAME, now, now, 0.0)
    assert g.answer(60, 0.0) is None
    assert g.counters["late_commands"] == 1 and g.counters["rejected_nonfinite"] == 1


def test_startup_settle_holds_the_first_step_then_takes_the_answers_of_a_resend():
    g = gate(startup_settle_s=0.5)
    for wall in (0.0, 0.3):
        g.on_planes(PLANES, planes_rad(0, 0, 0, 0, 0), FRAME, 0, 0, wall)
        g.on_propeller([PROP], [1.0], FRAME, 0, 0, wall)
        assert g.answer(0, wall) is None                  # held: readers matched late must miss nothing
    g.on_planes(PLANES, planes_rad(0, 0, 0, 0, 0), FRAME, 0, 0, 0.6)
    g.on_propeller([PROP], [1.0], FRAME, 0, 0, 0.6)
    assert g.answer(0, 0.6) is not None


def test_watchdog_resends_then_times_out_into_the_failsafe_with_held_commands():
    g = gate(lockstep_timeout_s=1.0, lockstep_retry_s=0.1)
    g.on_planes(PLANES, planes_rad(2, 2, 2, 2, 2), FRAME, 0, 0, 0.0)
    g.on_propeller([PROP], [2 * math.pi * 1.5], FRAME, 0, 0, 0.0)
    g.answer(0, 0.0)
    g.stepped()
    g.state_sent(10.0)                                    # step 1's state goes out
    assert g.watchdog(1, 10.05) == (WatchdogAction.NONE, None)
    assert g.watchdog(1, 10.15)[0] is WatchdogAction.RESEND
    assert g.watchdog(1, 10.2)[0] is WatchdogAction.NONE   # the re-send restarted the retry clock
    action, d = g.watchdog(1, 11.01)
    assert action is WatchdogAction.STEP and d.failsafe and g.failsafe
    assert "last valid planes" in d.reason and "propeller held" in d.reason
    np.testing.assert_allclose(d.planes_deg, [2] * 5, atol=1e-12)
    assert d.rps == pytest.approx(1.5)
    assert g.counters["lockstep_resends"] == 1 and g.counters["lockstep_timeouts"] == 1
    assert g.counters["failsafe_steps"] == 1 and g.counters["failsafe_steps_after_takeover"] == 1


def test_first_step_times_out_on_the_startup_timeout_with_the_safe_default():
    g = gate(startup_timeout_s=5.0)
    g.state_sent(0.0)
    assert g.watchdog(0, 4.9)[0] is WatchdogAction.RESEND
    action, d = g.watchdog(0, 5.1)
    assert action is WatchdogAction.STEP
    assert d.rps == 1.25 and np.all(d.planes_deg == 0) and "neutral planes" in d.reason and "nominal" in d.reason


def test_failsafe_releases_at_the_first_complete_answer():
    g = gate(lockstep_timeout_s=0.2)
    g.state_sent(0.0)
    g.stepped()
    _, d = g.watchdog(1, 0.3)
    assert d.failsafe
    g.stepped()
    g.state_sent(0.3)
    g.on_planes(PLANES, planes_rad(0, 0, 0, 0, 0), FRAME, 2 * NS // 20, 2 * NS // 20, 0.31)
    g.on_propeller([PROP], [1.0], FRAME, 2 * NS // 20, 2 * NS // 20, 0.31)
    d = g.answer(2, 0.31)
    assert d is not None and not d.failsafe and not g.failsafe and g.failsafe_reason == ""


# ------------------------------------------------------------------------------------------ real time
def test_realtime_failsafe_engages_on_silence_and_releases_on_fresh_commands():
    g = gate(TimeMode.REALTIME, command_timeout_s=0.5)
    d = g.realtime_commands(0.0)                          # nothing ever came
    assert d.failsafe and d.rps == 1.25 and np.all(d.planes_deg == 0) and "nominal" in d.reason
    g.on_planes(PLANES, planes_rad(3, 3, 3, 3, 3), FRAME, 0, 0, 1.0)
    g.on_propeller([PROP], [2 * math.pi * 2.0], FRAME, 0, 0, 1.0)
    d = g.realtime_commands(1.2)
    assert not d.failsafe and d.rps == pytest.approx(2.0) and not g.failsafe
    d = g.realtime_commands(1.6)                          # both stale now
    assert d.failsafe and np.all(d.planes_deg == 0) and d.rps == pytest.approx(2.0)
    assert "planes neutral, propeller held" in d.reason
    g.on_planes(PLANES, planes_rad(3, 3, 3, 3, 3), FRAME, 0, 0, 1.7)   # only the planes come back
    d = g.realtime_commands(1.8)
    assert d.failsafe and "no valid propeller command" in d.reason and "planes held" in d.reason
    np.testing.assert_allclose(d.planes_deg, [3] * 5, atol=1e-12)
    assert g.counters["failsafe_steps"] == 3
    # the first was the start-up wait for the controllers; the two after they had answered are counted apart
    assert g.took_over and g.counters["failsafe_steps_after_takeover"] == 2
    # the longest silence since the takeover: the planes' 1.0 -> 1.7 s (the propeller has not come back)
    assert g.command_gap_max_s == pytest.approx(0.7)


def test_startup_failsafe_steps_are_not_counted_after_the_takeover():
    g = gate(TimeMode.REALTIME, command_timeout_s=0.5)
    for w in (0.0, 0.05, 0.1):
        assert g.realtime_commands(w).failsafe and not g.took_over
    g.on_planes(PLANES, planes_rad(0, 0, 0, 0, 0), FRAME, 0, 0, 0.12)
    g.on_propeller([PROP], [1.0], FRAME, 0, 0, 0.12)
    assert not g.realtime_commands(0.15).failsafe and g.took_over
    assert g.counters["failsafe_steps"] == 3 and g.counters["failsafe_steps_after_takeover"] == 0
    assert g.command_gap_max_s == 0.0  # nothing came twice since the takeover
    for w in (0.17, 0.22, 0.30):
        g.on_planes(PLANES, planes_rad(0, 0, 0, 0, 0), FRAME, 0, 0, w)
        g.on_propeller([PROP], [1.0], FRAME, 0, 0, w + 0.01)
    assert g.command_gap_max_s == pytest.approx(0.08)


# ------------------------------------------------------------------------------------------ recorder back-pressure
def test_recorder_ack_lets_steps_go_within_the_window_and_holds_them_beyond():
    from bb2_mission.lockstep_gate import RecorderAck

    h = NS // 20
    a = RecorderAck(3, step_ns=h, t0_ns=0, timeout_s=10.0)
    assert all(a.may_step(n * h, 0.0) for n in range(3))  # nothing acknowledged yet: the first 3 steps go
    assert not a.may_step(3 * h, 1.0) and a.waits == 1 and a.waiting_since == 1.0
    assert not a.may_step(3 * h, 2.0) and a.waits == 1   # the same held step counts once
    a.on_ack(0)                                          # the recorder holds t_0: t_3 is 3 steps ahead
    assert a.may_step(3 * h, 2.5) and a.waiting_since is None
    assert not a.may_step(4 * h, 2.6) and a.waits == 2
    a.on_ack(5 * h)
    a.on_ack(2 * h)                                      # an older acknowledgement changes nothing
    assert a.acked_ns == 5 * h and a.lag_steps(8 * h) == 3 and a.may_step(8 * h, 3.0)
    assert not RecorderAck(0, step_ns=h).enabled and RecorderAck(0, step_ns=h).may_step(10**12, 0.0)
    with pytest.raises(ValueError):
        RecorderAck(-1, step_ns=h)


def test_recorder_ack_gives_a_silent_recorder_up_after_its_timeout_until_it_acknowledges_again():
    from bb2_mission.lockstep_gate import RecorderAck

    h = NS // 20
    a = RecorderAck(2, step_ns=h, t0_ns=0, timeout_s=5.0)
    a.on_ack(0)
    assert not a.may_step(3 * h, 10.0)
    assert not a.expired(14.9) and not a.given_up
    assert a.expired(15.0) and a.given_up and a.timeouts == 1
    assert not a.expired(30.0) and a.timeouts == 1      # said once
    assert a.may_step(50 * h, 31.0)                      # steps go without it
    a.on_ack(49 * h)                                     # it is back: the window holds again
    assert not a.given_up and a.may_step(51 * h, 32.0) and not a.may_step(52 * h, 32.1)


def test_real_time_first_commands_start_the_clock_resending_the_first_state_meanwhile():
    g = gate(TimeMode.REALTIME, startup_timeout_s=2.0)
    g.state_sent(10.0)  # the first state goes out at wall 10 s
    assert g.first_commands(10.05) is WatchdogAction.NONE
    assert g.first_commands(10.11) is WatchdogAction.RESEND and g.first_commands(10.15) is WatchdogAction.NONE
    assert g.first_commands(10.22) is WatchdogAction.RESEND and not g.has_commands
    g.on_planes(PLANES, planes_rad(0, 0, 0, 0, 0), FRAME, 0, 0, 10.25)
    assert g.first_commands(10.25) is WatchdogAction.NONE   # the planes alone do not start it
    g.on_propeller([PROP], [2 * math.pi], FRAME, 0, 0, 10.3)
    assert g.has_commands and g.first_commands(10.3) is WatchdogAction.STEP
    assert g.state_age_s(10.3) == pytest.approx(0.3)
    late = gate(TimeMode.REALTIME, startup_timeout_s=2.0)
    late.state_sent(10.0)
    assert late.first_commands(11.99) is WatchdogAction.RESEND   # none in time: the clock starts on the failsafe
    assert late.first_commands(12.0) is WatchdogAction.STEP and not late.has_commands


def test_the_simulators_own_stall_is_given_back_to_fresh_commands_once():
    g = gate(TimeMode.REALTIME, command_timeout_s=0.5)
    g.on_planes(PLANES, planes_rad(1, 1, 1, 1, 1), FRAME, 0, 0, 1.0)
    g.on_propeller([PROP], [1.0], FRAME, 0, 0, 1.01)
    assert not g.realtime_commands(1.05).failsafe
    g.simulator_stalled(1.1, 6.1)                         # the stepping thread stopped 5 s (SIGSTOP) after 1.1 s
    d = g.realtime_commands(6.1)                          # the controllers had nothing to answer meanwhile
    assert not d.failsafe and g.counters["failsafe_steps_after_takeover"] == 0
    assert g.realtime_commands(6.45).failsafe is False
    assert g.realtime_commands(6.55).failsafe             # then their own silence counts again
    # once per command: a second stall with no command since gives nothing back
    g.simulator_stalled(6.6, 9.0)
    assert g.realtime_commands(9.0).failsafe
    # a command that was already stale when a stall began gets nothing either
    h = gate(TimeMode.REALTIME, command_timeout_s=0.5)
    h.on_planes(PLANES, planes_rad(1, 1, 1, 1, 1), FRAME, 0, 0, 1.0)
    h.on_propeller([PROP], [1.0], FRAME, 0, 0, 1.0)
    h.simulator_stalled(1.6, 3.0)
    assert h.realtime_commands(3.0).failsafe
    # a fresh command after a credited stall can be credited again
    g.on_planes(PLANES, planes_rad(1, 1, 1, 1, 1), FRAME, 0, 0, 9.1)
    g.on_propeller([PROP], [1.0], FRAME, 0, 0, 9.1)
    g.simulator_stalled(9.2, 12.0)
    assert not g.realtime_commands(12.0).failsafe
