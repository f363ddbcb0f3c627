"""The streaming identifier agrees with the batch function sample for sample and re-arms between impacts."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactometer.errors import IdentificationError, ParameterError, StreamFinishedError
from impactometer.identify.peak_to_peak import identify_arrays
from impactometer.identify.peak_to_peak.streaming import StreamingIdentifier, stream_arrays
from impactometer.model import simulate
from impactometer.rig import Scenario

FS = 50e3


def impact(mass, velocity, seed, pre=2000, rig="drop-stand-stiff"):
    """Force and acceleration with 20 N and 5 m/s² of noise; by default on the stiff stand, where the early answer
    exists (on the pad stand the contact-phase fit refuses it)."""
    r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=2e5), rig, duration=0.08, sample_rate=FS)
    rng = np.random.default_rng(seed)
    f = np.r_[np.zeros(pre), r.contact_force] + 20.0 * rng.standard_normal(pre + r.time.size)
    a = np.r_[np.zeros(pre), r.a2] + 5.0 * rng.standard_normal(pre + r.time.size)
    return f, a


@pytest.mark.parametrize("chunk", [1, 7, 64, 4096])
def test_streaming_equals_batch(chunk):
    f, a = impact(30.0, 2.0, seed=3)
    batch = identify_arrays(f, a, FS, -0.04)
    ident = StreamingIdentifier(FS, start_time=-0.04)
    got = []
    for k in range(0, f.size, chunk):
        got.extend(ident.push(f[k:k + chunk], a[k:k + chunk]))
    final = ident.finish()
    assert final == batch  # identical numbers, early answer included
    assert got[0] == batch.early and got[0].available_at < got[-1].available_at
    assert [e.available_at for e in got] == sorted(e.available_at for e in got)


@pytest.mark.parametrize("chunk", [64, 4096])
def test_streaming_equals_batch_on_the_pad_stand(chunk):
    f, a = impact(30.0, 2.0, seed=3, rig="drop-stand")
    batch = identify_arrays(f, a, FS, -0.04)
    ident = StreamingIdentifier(FS, start_time=-0.04)
    got = []
    for k in range(0, f.size, chunk):
        got.extend(ident.push(f[k:k + chunk], a[k:k + chunk]))
    assert ident.finish() == batch and got[0].early == batch.early
    assert [e.available_at for e in got] == sorted(e.available_at for e in got)
    # no early answer on this stand, and every answer says why, the streaming ones as the batch one
    assert batch.early is None and "follow no law" in batch.early_reason
    assert {e.early_reason for e in got} == {batch.early_reason}


def test_the_early_reason_is_none_with_an_early_answer_and_names_the_variant_without_one():
    f, a = impact(30.0, 2.0, seed=3)
    robust = identify_arrays(f, a, FS, -0.04)
    assert robust.early is not None and robust.early_reason is None and robust.early.early_reason is None
    assert robust.to_dict()["early_reason"] is None
    paper = identify_arrays(f, a, FS, -0.04, variant="paper")
    assert paper.early is None and paper.to_dict()["early_reason"] == ("the paper variant gives no early answer "
                                                                       "(the robust variant does)")


def test_stage_b_updates_keep_coming_at_a_growing_spacing():
    """In sustained contact the answer is refined at UPDATE_INTERVAL at most, and each update comes when the impact
    has lasted UPDATE_GROWTH times as long as at the one before (seen from the first contact)."""
    from impactometer.identify.peak_to_peak.streaming import UPDATE_GROWTH, UPDATE_INTERVAL
    r = simulate(Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5), "drop-stand", duration=0.3, sample_rate=FS)
    rng = np.random.default_rng(4)
    pre = 2000
    f = np.r_[np.zeros(pre), r.contact_force] + 20.0 * rng.standard_normal(pre + r.time.size)
    a = np.r_[np.zeros(pre), r.a2] + 5.0 * rng.standard_normal(pre + r.time.size)
    ident = StreamingIdentifier(FS, start_time=-pre / FS)
    got = []
    for k in range(0, f.size, 64):
        got.extend(ident.push(f[k:k + 64], a[k:k + 64]))
    updates = [e.available_at for e in got if e.available_at > 0.04]  # well inside stage B
    assert len(updates) >= 2, updates
    chunk = 64 / FS
    for before, after in zip(updates, updates[1:], strict=False):
        assert after - before >= UPDATE_INTERVAL - chunk
        assert after >= UPDATE_GROWTH * before - 2 * chunk
        assert after <= UPDATE_GROWTH * before + 0.01  # no update is skipped: the answer keeps improving
    assert got[-1].mass_std <= got[0].mass_std


def test_rearms_for_the_next_impact_with_constant_memory():
    f1, a1 = impact(20.0, 1.5, seed=1)
    f2, a2 = impact(40.0, 2.5, seed=2)
    quiet = np.random.default_rng(0).normal(0, 20.0, 20000)
    f = np.r_[f1, quiet, f2, quiet]
    a = np.r_[a1, np.random.default_rng(1).normal(0, 5.0, 20000), a2, np.random.default_rng(2).normal(0, 5.0, 20000)]
    ident = StreamingIdentifier(FS)
    buffers = (ident._force.nbytes, ident._acc.nbytes)
    stream = []
    for k in range(0, f.size, 64):
        stream.extend(ident.push(f[k:k + 64], a[k:k + 64]))
    ident.finish()
    assert len(ident.completed) == 2
    assert ident.completed[0].mass == pytest.approx(20.0, rel=0.05)
    assert ident.completed[1].mass == pytest.approx(40.0, rel=0.05)
    assert ident.completed[1].velocity == pytest.approx(2.5, rel=0.01)
    assert (ident._force.nbytes, ident._acc.nbytes) == buffers
    assert stream_arrays(f, a, FS, chunk=256)[-1] == ident.completed[1]


def test_bad_chunks():
    ident = StreamingIdentifier(FS)
    with pytest.raises(IdentificationError, match="equal length"):
        ident.push(np.zeros(3), np.zeros(4))
    with pytest.raises(IdentificationError, match="non-finite"):
        ident.push(np.array([0.0, np.inf]), np.zeros(2))
    with pytest.raises(ParameterError, match="variant"):
        StreamingIdentifier(FS, variant="x")
    with pytest.raises(ParameterError, match="sample_rate"):
        StreamingIdentifier(-1.0)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.lists(st.integers(1, 700), min_size=1, max_size=12))
def test_random_signals_and_chunks(seed, chunks):
    """Random signals in random chunks: only finite, positive estimates, and at the end of a stream of one impact
    the batch function's answer or refusal on the same samples -- never another exception."""
    rng = np.random.default_rng(seed)
    ident = StreamingIdentifier(FS)
    forces, accelerations = [], []
    for size in chunks:
        f = rng.normal(0.0, 10.0, size) + (rng.random(size) < 0.02) * rng.uniform(0, 5e3, size)
        a = rng.normal(0.0, 3.0, size)
        forces.append(f)
        accelerations.append(a)
        for est in ident.push(f, a):
            assert np.isfinite(est.mass) and est.mass > 0 and np.isfinite(est.velocity)
    final = _outcome(ident.finish)
    if len(ident.outcomes) <= 1:
        batch = _outcome(lambda: identify_arrays(np.concatenate(forces), np.concatenate(accelerations), FS))
        if final is None or isinstance(final, IdentificationError):
            assert isinstance(batch, IdentificationError)
            assert final is None or str(final) == str(batch)
        else:
            assert final == batch


def _outcome(call):
    try:
        return call()
    except IdentificationError as exc:
        return exc


@pytest.mark.parametrize("damage, message", [
    (lambda f, a: (np.minimum(f, 0.3 * f.max()), a), "contact_force is saturated"),
    (lambda f, a: (f, np.zeros_like(a)), "piston_acceleration is constant"),
    (lambda f, a: (f, -a), "reads the impact with the other sign.*--flip-acceleration"),
])
def test_the_stream_refuses_what_the_batch_function_refuses(damage, message):
    f, a = damage(*impact(30.0, 2.0, seed=5))
    with pytest.raises(IdentificationError, match=message):
        identify_arrays(f, a, FS)
    ident = StreamingIdentifier(FS)
    estimates = []
    for k in range(0, f.size, 64):
        estimates += ident.push(f[k:k + 64], a[k:k + 64])
    with pytest.raises(IdentificationError, match=message):
        ident.finish()
    assert not ident.completed
    assert not estimates  # every answer, the early one included, passes the same checks: none went out


def test_streaming_equals_batch_paper_and_contact_phase():
    f, a = impact(40.0, 2.5, seed=4)
    for options in ({"variant": "paper"}, {"contact_phase": True}):
        batch = identify_arrays(f, a, FS, -0.04, **options)
        ident = StreamingIdentifier(FS, start_time=-0.04, **options)
        for k in range(0, f.size, 64):
            ident.push(f[k:k + 64], a[k:k + 64])
        assert ident.finish() == batch


def test_a_stream_that_only_triggers_and_buffers_gives_no_estimate():
    """``estimates=False``: the same trigger and the same buffered samples as the identifying stream, no estimate,
    no final answer, and it re-arms after the impact closes."""
    f1, a1 = impact(20.0, 1.5, seed=1)
    quiet = np.random.default_rng(0).normal(0, 20.0, 20000)
    f, a = np.r_[f1, quiet, f1], np.r_[a1, np.random.default_rng(1).normal(0, 5.0, 20000), a1]
    full, bare = StreamingIdentifier(FS), StreamingIdentifier(FS, estimates=False)
    triggers: list[tuple[int | None, int | None]] = []
    for k in range(0, f.size, 64):
        full.push(f[k:k + 64], a[k:k + 64])
        assert bare.push(f[k:k + 64], a[k:k + 64]) == []
        triggers.append((full.trigger_index, bare.trigger_index))
        if bare.trigger_index is not None:
            start = bare.impact_start
            assert all(np.array_equal(x, y) for x, y in zip(full.buffered(start, bare.seen),
                                                            bare.buffered(start, bare.seen), strict=True))
    assert all(x == y for x, y in triggers)
    assert len({t for t, _ in triggers if t is not None}) == 2  # two impacts, the stream re-armed between them
    assert full.estimates and bare.estimates == [] and bare.outcomes == []


def test_a_push_after_finish_is_refused():
    ident = StreamingIdentifier(50e3)
    ident.push(np.zeros(100), np.zeros(100))
    assert ident.finish() is None and ident.finish() is None  # finishing again changes nothing
    with pytest.raises(StreamFinishedError, match=r"push\(\) after finish\(\).*new one"):
        ident.push(np.zeros(10), np.zeros(10))
    with pytest.raises(RuntimeError):  # the builtin it matches
        ident.push(np.zeros(10), np.zeros(10))
