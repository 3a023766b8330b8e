"""Limits and vocabularies of the calibration model, declared once.

The library's parameter checks, the CLI's help and choices and the model-file
schema (``schemas/model-1.json``, checked against this table by the tests) all
read these names. The module imports nothing heavy, so ``ftcal --help`` can use it.
"""

from __future__ import annotations

MAX_DEGREE = 10
"""Highest polynomial degree np (degree 5 over 7 inputs is already 792 terms per output)."""

INFO_TERMS = 10
"""How many of a polynomial model's largest terms ``ftcal info`` (:func:`ftcal.workflow.info.model_info`) lists by
default."""

MAX_LAG = 50
"""Highest ARX order na (past outputs) and nb (input lags)."""

NORMALIZATIONS = ("center", "maxabs")
"""Input bases. ``maxabs`` (u / max|u|) with max-abs column scaling is the paper's basis;
``center`` maps each input's range onto [-1, 1], which keeps high degrees well conditioned."""

PENALTIES = ("none", "ridge", "lasso")
"""Penalty kinds: least squares, ½λ‖θ‖² (ridge) and λ‖θ‖₁ (LASSO), on max-abs scaled columns."""

SOLVERS = ("lstsq", "osqp")
"""``lstsq``: ftcal's streaming exact solvers; ``osqp``: the paper's QPs on the dense regressor."""

PREDICTION_MODES = ("one-step", "free-run")
"""ARX prediction: measured past outputs (the paper's evaluation, default) or fed-back predictions."""

TARE_MODES = ("none", "first-hold", "per-file")
"""How evaluate/report re-tare held-out recordings (:mod:`ftcal.data.tare`): not, each recording at its first
static hold, or once per file."""

FREE_RUN_STARTS = ("zeros", "measured")
"""Free-run history before the first sample: zeros (the paper's code) or the first measured output."""

ARX_WARMUP = ("drop", "keep")
"""Metrics over ARX predictions: drop the first max(na, nb) rows of each segment (the paper's code) or keep them."""

PAPER_LAMBDAS = (0.5, 1.0, 10.0, 50.0, 100.0, 200.0)
"""The LASSO weights of the paper's Table III."""

# ``ftcal check``: conventions and acceptance (read by ftcal.check and the CLI's help).

HOLD_SAMPLE_RATE = 100.0
"""Hz: rows of a table without a time column are this far apart when finding its static holds (--rate)."""

MIN_HOLDS = 3
"""Fewest static holds at different orientations ``ftcal check`` needs."""

MIN_ROTATION_DEG = 1.0
"""Smallest frame rotation reported: below it a mounting error is within machining tolerance."""

FINDING_CONFIDENCE = 0.999
"""A convention finding needs this confidence (1 − p-value of its likelihood-ratio test)."""

MAX_COM_DISTANCE = 0.3
"""m. A tool's centre of mass farther than this from the sensor origin is implausible (torques
about another point); ``--max-com-distance`` changes it."""

MAX_FORCE_ERROR = 1.0
"""N, default acceptance threshold on each force axis' RMS error (and on any pose's)."""

MAX_TORQUE_ERROR = 0.1
"""N·m, default acceptance threshold on each torque axis' RMS error (and on any pose's)."""

MIN_TOOL_MASS = 0.05
"""kg. ``ftcal check`` calls a stream gravity-compensated when the tool it sees is confidently lighter."""

# ``ftcal plan``: experiment design.

PLAN_OBJECTIVES = ("calibration", "payload")
"""What ``ftcal plan`` designs for: a polynomial calibration of the given degree, or bias + mass + COM."""

MAX_PLAN_POSES = 100_000
"""Most poses ``ftcal plan`` designs."""

MAX_PLAN_CANDIDATES = 10_000_000
"""Most random joint configurations ``ftcal plan`` draws to choose from."""

PLAN_DEFAULTS = {"candidates": 10_000, "reference_every": 10, "degree": 2, "noise": (0.1, 0.01)}
"""``ftcal plan`` defaults: candidate configurations, poses between returns to the reference pose,
calibration degree, and per-pose noise (N, N m) behind the predicted standard errors."""

# Model families (``ftcal fit --family``).

FAMILY_NAMES = ("polynomial", "mlp")
"""Model families this ftcal ships (``core.families.FAMILIES``; ``ftcal fit --family``)."""

MLP_ACTIVATIONS = ("tanh", "relu")
"""Hidden-layer activations of the MLP family (each has an ONNX operator and a C expression)."""

MLP_MAX_LAYERS = 4
"""Most hidden layers of an MLP (a calibration map needs one or two)."""

MLP_MAX_UNITS = 256
"""Most units per hidden layer (the generated C is straight-line: one statement per unit)."""

MLP_MAX_ITER = 100_000
"""Most L-BFGS iterations of one MLP training run."""

MLP_EQUATIONS_PER_WEIGHT = 5
"""``fit --family mlp`` sizes its default network to at most one weight per this many equations (rows ×
outputs); 418 rows of 8 inputs and 6 outputs give 8-20-10-6, the fingertip sensor authors' recipe."""

# ``ftcal payload``: weighting, bias drift and robust standard errors.

PAYLOAD_WEIGHTINGS = ("auto", "ols", "wls")
"""Payload fits: per-axis weighting chosen by held-out evidence, plain least squares, or per-axis 1/σ²."""

BIAS_DRIFTS = ("none", "linear", "random-walk", "auto")
"""Bias over a payload recording: constant, affine in time, a random walk (state-space model), or chosen
by evidence (BIC, the simpler model unless the evidence is strong)."""

ROBUST_CLUSTERS = 20
"""Contiguous time blocks of a payload recording for cluster-robust standard errors and held-out folds."""

DRIFT_BLOCKS = 1000
"""Most time blocks (equal sample counts) the random-walk bias model is fitted on."""

DRIFT_BLOCK_SECONDS = 1.0
"""Shortest time block of the random-walk bias model, s: faster wandering is noise, slower is drift."""

UNDETERMINED_EFFECT = 0.01
"""Compensation with a payload some of whose parameters the poses did not determine: a sample is outside
the poses' span when an undetermined direction moves its wrench by more than this fraction of the wrench
the same change would make at the worst pose (0.01: gravity tilted about 0.6° out of the recorded span)."""

# ``ftcal fit --degree auto``: selection per output and its cost.

SELECT_PER = ("output", "block", "model")
"""What ``--degree auto`` selects a degree, penalty and λ for: each output, the force and the torque
blocks, or one model for all outputs."""

OBJECTIVES = ("both", "force", "torque")
"""What ranks candidates that serve several outputs: force and torque (each relative to the affine
model, averaged), or one block alone."""

SELECTION_BUDGET_SECONDS = 20.0
"""Default ``--budget``: degrees whose estimated cost would exceed it are not tried (the search says so)."""

SELECTION_MEMORY_BYTES = 1_000_000_000
"""Degrees whose estimated peak memory (statistics and eigen-decompositions held per fold) exceeds this are
not tried."""

SATURATION_RATIO = 0.5
"""Least-squares fits warn when coefficients per output exceed this fraction of the distinct poses."""

POSE_BINS = 20
"""Distinct poses are counted as occupied cells of a grid with this many bins per input over its range
(5 % of the range: a static load case with its noise is one cell, a sweep one cell per 5 % step)."""

# --- Limits on what a file may make ftcal do (docs/security.md lists each with its reason). ---
# ftcal trusts its command line, not the files it reads: every reader checks what a file declares
# against these before it allocates or loops.

MAX_MODEL_BYTES = 100 * 10**6
# A model file's envelope (ftcal.files.model_json.check_envelope_consistency; ftcal.files.model_info mirrors
# it without numpy): the smallest normalization scale (float64's smallest normal number, numpy's finfo.tiny),
# and how far a stored input covariance may be from symmetric (relative to its largest |variance|) and
# below positive semi-definite (its smallest eigenvalue, relative to that variance times the size).
MIN_SCALE = 2.2250738585072014e-308
COVARIANCE_ASYMMETRY = 1e-9
COVARIANCE_NEGATIVE = 1e-9
"""Largest model or payload file (JSON or paper XML): degree 10 over 7 inputs is ~2 MB of text."""

MAX_TEXT_FILE_BYTES = 50 * 10**6
"""Largest URDF, TOML load-case file or other text configuration read whole into memory."""

MAX_TABLE_COLUMNS = 10_000
"""Most columns in a CSV or Parquet table (a calibration table has tens; a malformed header can claim millions)."""

MAX_HEADER_BYTES = 10**6
"""Longest CSV header line read to learn the column names; also the most bytes of one MATLAB v5 array's
dimensions, name or field names."""

MAX_DECLARED_ELEMENTS = 2 * 10**9
"""Most numbers one array in a .mat log may declare (16 GB of float64); checked before reading it."""

MAX_MAT_ARRAYS = 1_000_000
"""Most arrays (struct fields, cell elements, HDF5 objects) one .mat log may hold: the logger writes tens to
thousands; a few compressed bytes can declare billions of empty ones, each a step of the reader."""

MAX_NESTING = 32
"""Deepest nesting of groups (v7.3, HDF5) or structs and cells (v5) in a .mat log: the logger's structs are a
few levels deep; deeper means a hostile file (link loops are refused as such). (JSON and XML nesting is bounded
by the parsers' recursion limit, caught as a one-line refusal.)"""

MAX_GRAM_BYTES = 4 * 10**9
"""Largest Gram matrix of a fit (p² doubles for p regressor columns per output), checked before it is
allocated: degree 10 over 7 inputs (19,448 columns, 3.0 GB) fits; ARX na = nb = 50 at degree 5
(40,642 columns, 13 GB, and a fit holds a few copies) does not."""

MAX_OPTION_MAGNITUDE = 1e12
"""Largest magnitude of a number option (--g, --gravity, --lasso, --payload-mass, ...): physical values
are far smaller, and values near 1e308 overflow the first product they meet."""

MAX_CELL_MAGNITUDE = 1e100
"""Largest magnitude of a number in a table: sums of squares and products of such values still fit in
float64 (about 1e308); larger ones are corrupt data, and would make fits overflow into NaN."""

MAX_BAG_TIMESTAMP_NS = 4 * 10**18
"""ns since the Unix epoch (year 2096): a ROS 2 bag's message timestamps must lie in [0, this]; larger
values overflow rosbags' int64 arithmetic (``MAX(timestamp) + 1``) or mean a corrupt row."""

ZERO_REFERENCE_WRENCH = 1e-6
"""N and N m: an expected wrench below this on every axis of every sample of a recording is zero
(nothing beyond the sensor): ``ftcal dataset`` says so loudly."""

EXACT_FIT = 1e-9
"""Relative: a training RMSE below this times the output's standard deviation (BestFit above 1 − this)
means the outputs are an exact function of the inputs (a copied column?): ``ftcal fit`` says so."""

# Physical plausibility of loads and payload files (issue 28: absurd values passed silently).

MAX_LOAD_MASS = 1000.0
"""kg. Heaviest load or payload ftcal accepts (a --load, --payload or load-case mass, a payload file's mass):
the largest six-axis sensors carry a few hundred kilograms; beyond this a value is a typo or a hostile file."""

MAX_LOAD_DISTANCE = 10.0
"""m. Farthest centre of mass of a load from its frame (and of a payload file's from the sensor origin)."""

GRAVITY_RANGE = (0.1, 100.0)
"""m/s². A payload file's gravity magnitude must lie in this range (the Moon's 1.62 to well above any planet)."""

MAX_WRENCH = 1e6
"""N or N·m. Largest bias a payload file may hold: sensors are rated far below this."""

MAX_PLAN_WORK = 5e10
"""Arithmetic operations ``ftcal plan`` may spend on one design (candidate rows × parameters², plus
parameters³): degree 6 with 10,000 configurations × 2 loads (1.7·10¹⁰) takes about 8 s of CPU here;
degree 10 (8,008 parameters) would take tens of minutes and is refused with what to lower."""

JOINT_LIMIT_SLACK = 6.283185307179586
"""rad (m for prismatic joints). Joint data more than a full turn (2π) beyond a URDF position limit is
refused: degrees read as radians, or another robot's log. Less is kept: encoders and simulators overshoot."""

MAX_TIME_STEP_S = 1e5
"""s. A time column whose median step between samples exceeds this (a day), or whose values exceed
:data:`MAX_TIME_S`, is in another unit (nanoseconds from a ROS bag or a logger): refused, saying so."""

MAX_TIME_S = 1e13
"""s. About 300,000 years: a larger time value is nanoseconds (1.7e18 since 1970) or microseconds."""

MAX_SIMULATED_SAMPLES = 2_000_000
"""F/T samples one ``ftcal simulate`` session may hold (rate × the session's motion, all recordings): a session
is simulated in memory, about 1.5 kB per F/T sample when writing bags and 0.6 kB for tables (measured:
852 MB peak for 450,589 samples at 8 kHz as a bag), so this is about 3 GB; 1 kHz for 33 minutes fits.
Checked before any folder or file is made (``--rate 1e9`` asked for 77 GiB and left an empty folder)."""

SIMULATE_MISTAKES = ("none", "sign", "swap-xy", "rotate-z")
"""Mounting mistakes ``ftcal simulate --mistake`` can make (``rotate-z`` takes an angle: ``rotate-z:DEG``)."""

SIMULATE_CHANNELS = ("wrench", "raw")
"""What a simulated recording's F/T channels hold: the driver's factory-calibrated wrench, or ADC counts."""

SIMULATE_FORMATS = ("bag", "table")
"""What ``ftcal simulate`` writes per recording: a ROS 2 bag folder, a robot-log table (Parquet)."""

# A static fit's training error from its summed statistics, yᵀy − 2θᵀAᵀy + θᵀAᵀAθ, loses about
# log10(yᵀy / ‖r‖²) of float64's ~16 digits to cancellation; beyond this many the fit scores the
# samples in a pass instead (a near-exact fit, or targets far from zero).
STATISTICS_ERROR_DIGITS = 7
MISSING_JOINTS = ("refuse", "zero")
"""What ``ftcal expected --missing-joints`` does with a joint the expected wrench depends on (on the chain
from the base to the sensor, or beyond the sensor) that the joints table lacks: refuse it, or hold it at 0 rad
because the user says it is 0."""

LIVE_MIN_HOLDS = 3
"""Fewest static holds (in different orientations) an identification in place takes, in Python and in the C runtime."""

C_RUNTIME_MAX_HOLDS = 32
"""Static holds the generated C runtime's state keeps for an identification in place (fixed size, no allocation):
holds past it are counted (``holds_dropped``) and left out, so the tool is identified from the first ones."""

C_RUNTIME_MAX_TOOLS = 8
"""Tools the generated C runtime's state can add at run time (identified in place under a new name), beside the
compiled-in ones: fixed-size slots; a tool identified under a name the library has replaces that tool instead."""

C_RUNTIME_MAX_TOOL_NAME = 63
"""Longest tool name, in bytes (UTF-8, without the terminating NUL), the generated C runtime copies into a slot at
run time; a longer or empty name is refused."""

C_RUNTIME_MAX_EVENTS = 64
"""Events (tool switched, identifying, identified, re-tare, flag raised or cleared) the generated C runtime's state
keeps in a ring (fixed size, no allocation): past it the oldest is overwritten and counted; a user may ``#define
NAME_MAX_EVENTS`` before including the header to keep another number."""

LIVE_KEY_CONVENTIONS = ("bridge", "rmw_zenoh")
"""Zenoh key expressions of ``ftcal live --zenoh``'s ROS topics: zenoh-bridge-ros2dds's (topic ``/ft/raw`` is key
``ft/raw``) or rmw_zenoh's (``<domain>/<topic>/<DDS type>/<RIHS01 type hash>``, with attachments and liveliness)."""

MAX_ROS_DOMAIN_ID = 232
"""Highest ROS 2 domain id (ROS 2's documented range is 0-232; rmw_zenoh puts it at the head of every key)."""

MAX_RT_PRIORITY = 99
"""Highest SCHED_FIFO priority on Linux (``ftcal live --rt-priority``; 1 is the lowest real-time priority)."""

LIVE_DIAGNOSTICS_PERIOD_S = 1.0
"""``ftcal live --zenoh`` publishes its diagnostics this often (ROS's ``diagnostic_updater`` default period, 1 s), and
also when a flag changes (as ``diagnostic_updater::Updater::force_update``), but then no sooner than
:data:`LIVE_DIAGNOSTICS_MIN_INTERVAL_S` after the previous message."""

LIVE_DIAGNOSTICS_MIN_INTERVAL_S = 0.05
"""Least time between two diagnostics messages of ``ftcal live --zenoh`` (at most 20 a second however often flags
change: a flag that comes and goes between two messages is still reported, in the next message's ``raised``)."""

LIVE_MAX_STATE_BYTES = 64 * 1024 * 1024
"""Largest live state file (``ftcal live --state``) read back: the state is a few kB plus the payload documents of the
tools identified in place; anything much larger is not a state file."""

LIVE_MAX_STAMP_JUMP_S = 60.0
"""``ftcal live --zenoh``: a wrench stamped this much later than the previous one is held back until the next message
confirms the new time line (a lone far-future stamp would otherwise make every later message look old)."""

LIVE_MAX_QUERY_BYTES = 4096
"""Longest payload of a ``ftcal live --zenoh`` queryable request (a tool name, ``start NAME``); longer ones are
answered with an error."""

LIVE_MAX_TOPIC_BYTES = 255
"""Longest topic (or ``--prefix``) of ``ftcal live --zenoh``, in UTF-8 bytes: ROS 2's own limit on a topic name
(``RMW_TOPIC_MAX_NAME_LENGTH``). Zenoh aborts the whole process (a Rust panic, SIGABRT) when it sends a peer the
declaration of a key longer than its 65,535-byte batch."""

LIVE_CLOCK_RESTART_MESSAGES = 100
"""``ftcal live --zenoh``: this many wrenches in a row stamped before the last one processed, in their own order, mean
the publisher's clock restarted (e.g. simulated time): the calibrator's clock restarts on them (said in one line)."""
