"""``TEMPLATE``: a commented example session configuration (every key with a typical value;
the reference of every key, generated from the schema, is :func:`msk.config.config_reference`).
"""

__all__ = ["TEMPLATE"]

TEMPLATE = """\
# msk session configuration. Paths are relative to this file. Units are SI unless the key says.

[subject]
name = "PS"            # used in the report
mass_kg = 75.0         # body mass; the static trial's plates are checked against it. Omitted:
                       # the C3D's stored mass, else the static's plates (summary: mass_source)
height_m = 1.70
sex = "male"           # "male" | "female": picks the anthropometric table rows
side = "left"          # side of interest (instrumented knee, affected limb)

[model]
source = "gait2392"                  # a shipped model by name, an msk model file (.toml) or a .osim
knee = "spline"                      # "spline" (gait2392 knee) | "four_bar" (crossed four-bar knee)
scale = true                         # scale to the static trial's marker distances
# markers = "gait2392_Scale_MarkerSet.xml"   # OpenSim marker set of a .osim without markers

# One [[trials]] table per recording. role: static | mass_identification | mvc | task | fes
# (A session may hold only FES trials: [model] is then optional and the gait stages are skipped.)
# Several task trials: `msk run` analyses each into its own folder, <out>/<trial name>/.
[[trials]]
name = "static"
file = "../data/gc5-PS/PS_static_for_scaling.trc"
role = "static"

[[trials]]
name = "gait1"
file = "../data/gc5-PS/PS_ngait_og_ss1.c3d"
role = "task"
contact_force = "../data/gc5-PS/PS_ngait_og_ss1_eTibia.csv"   # optional measured knee force
# A task trial may be an OpenSim .trc (markers, +y up) with its forces in an OpenSim GRF .mot
# (ground_force_v*, ground_force_p*, ground_torque_* and 1_ground_… : one set per plate):
# file = "subject01_walk.trc"
# grf = "subject01_walk_grf.mot"   # same frame as the .trc (only with a .trc file)
# external_loads = "subject01_walk_grf.xml"   # OpenSim ExternalLoads: which body each force acts on

[markers]
# model marker name = lab label, when they differ
rename = {}
# IK weights by model marker name (default 1.0)
weights = {}
# model markers a lab places where it likes (thigh / shank clusters): moved to where the static
# trial puts them on their body (OpenSim's move_model_markers for these markers)
move = []

[emg]
# model muscle (or muscle group) = analog channel label
channels = { vas_med_l = "vasmed", vas_lat_l = "vaslat", rect_fem_l = "rf" }
highpass_hz = 20.0
lowpass_hz = 6.0
electromechanical_delay_s = 0.04
# MVC envelope peak per channel (analog units): activations then relative to MVC, not to the
# session's own peak; or give MVC recordings as [[trials]] with role = "mvc"
# mvc = { vasmed = 0.31, vaslat = 0.29 }

[loads]
# explicit plate → body assignment (plates named plate1, plate2… in file order); default automatic
assign = {}

[contact]
# medial–lateral distance of the two tibiofemoral contact points (m); default: 40 mm scaled by
# the model's tibia (Lerner et al. 2015)
# intercondylar_distance_m = 0.04

[filters]
kinematics_cutoff_hz = 6.0
grf_cutoff_hz = 6.0               # default: the kinematics' cut-off (the same filter on both)
acceleration_domain = "coordinates"  # or "segment_com": the COM low-passed as the plates (running)

[optimization]
# static_optimization | bounded_qp | emg_weighted | emg_assisted | closed_form
method = "static_optimization"
w_emg = 0.1                      # EMG weight of the EMG-weighted QP (Hayashibe et al. 2011, Eq. 18)
w_track = 1.0                    # emg_assisted: weight of Σ (a_i − g_c ê_i)², gains fitted
solver = "daqp"
activation_weights = "uniform"   # static_optimization, emg_assisted: uniform | volume (Σ V a^p)
activation_exponent = 2.0        # static_optimization: p ≥ 2 (OpenSim's activation_exponent)

# FES knee-model identification (Benoussaad et al. 2013): one [[trials]] table per recording with
# role = "fes" and fes_step = static | pendulum | isometric | recruitment | dynamic | validation
# (needs subject.height_m; at least 3 isometric and 3 recruitment trains). CSV files (header
# row) or C3D files (analog channels). The keys below are valid only with role = "fes".
# [[trials]]
# name = "fes_pendulum"
# file = "../data/fes/pendulum.csv"
# role = "fes"
# fes_step = "pendulum"
# time_column = "time"              # CSV only (s); a C3D uses its analog time
# angle_channel = "knee_angle"      # goniometer column / analog label (0 = full extension)
# torque_channel = "torque"         # dynamometer torque (N·m)
# stimulation_channel = "pw"        # stimulation level column / analog label
# angle_unit = "deg"                # deg | rad
# stimulation_unit = "us"           # us | s (pulse width) | mA | A (current)
# knee_angle_deg = 60.0             # isometric / recruitment: the dynamometer angle when the
#                                   # file has no angle channel

# [fes]
# fibre_fraction = 0.195    # prior L_c0/(L_c0 + L_s); default: the Table 3 population mean
# stiffness_ratio = 741.0   # prior K_cm/F_cm (1/m); default: the Table 3 population mean
#                           # (Benoussaad et al. 2013, Table 3: msk.fes.priors)
# k_s0 = 5000.0             # initial series stiffness of the NLP (N/m, literature value)
# outer_iterations = 6      # fixed-point passes on k_s (1 = the seed's single pass)
# frequency_hz = 20.0       # stimulation frequency
# steady_window_s = 0.5     # end-of-train window of the steady isometric torque
# isometric_transients = false   # refit on the torque time courses (short trains)
# theta_rest_deg = 90.0     # knee angle of the hanging shank (rest)
"""
