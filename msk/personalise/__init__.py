"""A generic model made the subject's: scaling from a static trial, marker placement (static or from
the motion),
the static trial's still window, functional joint centres, the femur:tibia split, and what the
markers leave
undetermined (determinacy, the sole-level prior)."""

__all__: list[str] = []
