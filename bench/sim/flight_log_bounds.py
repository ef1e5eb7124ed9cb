"""The bounds a flight log is read within (docs/FLIGHT_LOG.md, "Bounds").

A log is data from outside: its sizes and values are checked against these
before anything is allocated or computed, so a hostile or careless file is
refused with one line naming the field instead of exhausting memory,
following a link out of the file, or overflowing into an answer of nulls.
Each bound is far beyond what a small spacecraft's log holds.
"""

from __future__ import annotations

import math

# Sizes, checked from the file's metadata before a dataset is read.
MAX_ROWS = 10_000_000  # samples per stream: 10 Hz for 11 days, 1 kHz for 2.7 hours
MAX_COLUMNS = 64  # values per sample (the valves' on-times: one per thruster, at most 32)
MAX_DATASET_BYTES = 1 << 30  # one field, as stored
MAX_LOG_BYTES = 2 << 30  # all fields together, as stored
MAX_MEMBERS = 32  # streams in a file, fields in a stream
MAX_JSON_BYTES = 1 << 20  # description_json, config_json
MAX_JSON_DEPTH = 32  # nesting of their objects and lists
MAX_JSON_INT_DIGITS = 18  # an integer in them (beyond: not a count or an index of this format)

# Values: a time stamp (any epoch; 1e10 s is the year 2286 as Unix time),
# and the magnitude of each kind of sample.
MAX_STAMP_S = 1e10
MAX_ACCEL_MPS2 = 1e4  # 1000 g
MAX_RATE_RPS = 1e3
MAX_POSITION_M = 1e8  # beyond any orbit the description allows
MAX_VELOCITY_MPS = 1e5
MAX_ON_TIME_S = 1e4  # one valve command's open time
POSE_R_SIGMA_M = (1e-6, 1e4)
POSE_ATT_SIGMA_RAD = (1e-6, math.pi)
MAX_VALUE = 1e12  # any other field (covariances, innovations, NIS)
