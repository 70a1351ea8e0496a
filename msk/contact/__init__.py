"""Joint contact forces: the tibiofemoral contact from the tibia free-body diagram, medial/lateral
split."""
