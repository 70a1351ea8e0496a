"""A replayed C3D streamed through a Lab Streaming Layer outlet → inlet pair on the loopback:
every frame back, in order, bit for bit, and the same live results as the replay without LSL."""

from __future__ import annotations

import numpy as np
import pytest

from msk.datasets.trials import make_trial
from msk.exceptions import MissingDataError
from msk.live import LiveOptions, LiveSession, live_model
from msk.live.sinks import CallbackSink, FrameRecorder, LslSink, result_channels
from msk.live.sources import LslInputOutlet, LslSource, ReplaySource, StreamLayout, load_pylsl
from tests.support.two_legs import muscled_two_legs


@pytest.fixture(scope="module")
def replay(tmp_path_factory):
    model = muscled_two_legs()
    tr = make_trial(model, duration_s=0.5, rate_hz=100.0, noise_m=0.0005, seed=5)
    path = tr.write_c3d(tmp_path_factory.mktemp("live") / "walk.c3d")
    return model, ReplaySource(path)


def _lsl():
    try:
        return load_pylsl()
    except MissingDataError as exc:  # only when liblsl cannot be loaded
        pytest.skip(str(exc))


def test_replay_reads_the_trial(replay):
    _, src = replay
    assert len(src) == 50 and src.rate_hz == 100.0
    assert src.plate_force is not None and src.plate_force.shape == (50, 2, 3)
    frames = list(src)
    assert [f.time for f in frames] == list(src.time)
    # loaded plates push up (+y in this lab)
    assert (src.plate_force[:, :, 1].sum(axis=1) > 100.0).all()


def test_stream_layout_round_trip(replay):
    _, src = replay
    lay = src.layout
    buf = np.empty(lay.n_channels)
    f = src.frame(7)
    g = lay.decode(lay.encode(f, buf).copy())
    assert g.time == f.time
    for name in ("markers", "plate_force", "plate_moment", "emg"):
        np.testing.assert_array_equal(getattr(g, name), getattr(f, name))
    assert StreamLayout(("a",), 1, ("e",)).n_channels == 1 + 3 + 6 + 1


def test_lsl_loopback_gives_every_frame_in_order_and_the_same_results(replay):
    _lsl()
    model, src = replay
    name = "msk-test-live-input"
    outlet = LslInputOutlet(name, src.layout, src.rate_hz)
    inlet = LslSource(name, timeout_s=10.0, idle_s=3.0, max_frames=len(src))
    assert inlet.layout == src.layout and inlet.rate_hz == src.rate_hz
    outlet.wait_for_consumers(5.0)
    for frame in src:
        outlet.push(frame)
    got = list(inlet)
    assert len(got) == len(src)
    for k, g in enumerate(got):
        f = src.frame(k)
        assert g.time == f.time
        np.testing.assert_array_equal(g.markers, f.markers)
        np.testing.assert_array_equal(g.plate_force, f.plate_force)
        np.testing.assert_array_equal(g.plate_moment, f.plate_moment)

    lm = live_model(model, src.labels, src.rate_hz, options=LiveOptions(knee_joint="knee_l"))
    direct, streamed = LiveSession(lm), LiveSession(lm)
    a, b = FrameRecorder(lm), FrameRecorder(lm)
    seen: list[float] = []
    for f, g in zip(src, got, strict=True):
        a(direct.step(f))
        out = streamed.step(g)
        b(out)
        CallbackSink(lambda fr: seen.append(fr.time))(out)
    assert seen == list(src.time)
    ta, tb = a.tables(700.0), b.tables(700.0)
    for key in ("q", "joint_torques", "muscle_forces", "knee_contact"):
        np.testing.assert_array_equal(ta[key].data, tb[key].data)


def test_lsl_sink_publishes_the_results(replay):
    lsl = _lsl()
    model, src = replay
    lm = live_model(model, src.labels, src.rate_hz, options=LiveOptions(knee_joint="knee_r"))
    sink = LslSink("msk-test-live-results", lm)
    found = lsl.resolve_byprop("name", "msk-test-live-results", 1, 10.0)
    inlet = lsl.StreamInlet(found[0])
    inlet.open_stream(10.0)
    sink.outlet.wait_for_consumers(5.0)
    session = LiveSession(lm)
    sent = []
    for k in range(5):
        out = session.step(src.frame(k))
        sink(out)
        sent.append(out)
    chans = result_channels(lm)
    assert inlet.info().channel_count() == len(chans)
    for out in sent:
        sample, _ = inlet.pull_sample(timeout=5.0)
        assert sample is not None
        assert sample[0] == out.time
        np.testing.assert_array_equal(sample[1 : 1 + lm.n_coords], out.q)
        assert sample[chans.index("knee_axial")] == out.knee_axial
