"""Live mode: the chain of ``msk run`` on a stream, one frame at a time (causal filtering, warm
starts), from a replayed trial or a Lab Streaming Layer inlet to a callback or an LSL outlet."""

from msk.live.session import (
    STAGES,
    LiveData,
    LiveFrame,
    LiveInput,
    LiveModel,
    LiveOptions,
    LiveSession,
    live_data,
    live_model,
    live_step,
)

__all__ = [
    "STAGES",
    "LiveData",
    "LiveFrame",
    "LiveInput",
    "LiveModel",
    "LiveOptions",
    "LiveSession",
    "live_data",
    "live_model",
    "live_step",
]
