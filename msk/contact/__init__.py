"""Joint contact forces: the tibiofemoral contact from the tibia free-body diagram, medial/lateral
split."""

__all__: list[str] = []
