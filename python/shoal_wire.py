"""ctypes mirrors of Shoal's wire types, for the official Python iceoryx2 client.

Each class has the type name and C layout of its Rust twin in broker/src/wire.rs.
"""

import ctypes

MAX_NEIGHBOURS = 16
MAX_BEAMS = 361
MAX_SHOWN_PARTICLES = 256
MAX_MAP_SIDE = 128


class Pose(ctypes.Structure):
    """`shoal.Pose`: one robot's state after one control period."""

    _fields_ = [
        ("agent_id", ctypes.c_uint32),
        ("pid", ctypes.c_uint32),
        ("tick", ctypes.c_uint64),
        ("sim_time", ctypes.c_double),
        ("x", ctypes.c_double),
        ("y", ctypes.c_double),
        ("theta", ctypes.c_double),
        ("believed_x", ctypes.c_double),
        ("believed_y", ctypes.c_double),
        ("believed_theta", ctypes.c_double),
        ("vx", ctypes.c_double),
        ("vy", ctypes.c_double),
        ("command", ctypes.c_uint32),
        ("health", ctypes.c_uint32),
        ("visible", ctypes.c_uint32),
        ("neighbour_count", ctypes.c_uint32),
        ("neighbours", ctypes.c_uint32 * MAX_NEIGHBOURS),
        ("missed_periods", ctypes.c_uint32),
        ("neighbour_age_ms", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name() -> str:
        return "shoal.Pose"


class ClockTick(ctypes.Structure):
    """`shoal.ClockTick`: one beat of the lockstep clock."""

    _fields_ = [("tick", ctypes.c_uint64), ("sim_time", ctypes.c_double), ("period_s", ctypes.c_double)]

    @staticmethod
    def type_name() -> str:
        return "shoal.ClockTick"


class Scan(ctypes.Structure):
    """`shoal.Scan`: a range scan after an executed command."""

    _fields_ = [
        ("agent_id", ctypes.c_uint32),
        ("pid", ctypes.c_uint32),
        ("tick", ctypes.c_uint64),
        ("sim_time", ctypes.c_double),
        ("command", ctypes.c_uint32),
        ("bumped", ctypes.c_uint32),
        ("beam_count", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("field_of_view", ctypes.c_double),
        ("max_range", ctypes.c_double),
        ("ranges", ctypes.c_float * MAX_BEAMS),
    ]

    @staticmethod
    def type_name() -> str:
        return "shoal.Scan"


class Estimate(ctypes.Structure):
    """`shoal.Estimate`: a SLAM pose estimate."""

    _fields_ = [
        ("agent_id", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("tick", ctypes.c_uint64),
        ("x", ctypes.c_double),
        ("y", ctypes.c_double),
        ("theta", ctypes.c_double),
        ("effective_particles", ctypes.c_double),
    ]

    @staticmethod
    def type_name() -> str:
        return "shoal.Estimate"


class ModelUpdate(ctypes.Structure):
    """`shoal.ModelUpdate`: one learned mixture (command, parameter D/C/T)."""

    _fields_ = [
        ("agent_id", ctypes.c_uint32),
        ("command", ctypes.c_uint32),
        ("param", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("step", ctypes.c_uint64),
        ("weights", ctypes.c_double * 2),
        ("means", ctypes.c_double * 2),
        ("variances", ctypes.c_double * 2),
    ]

    @staticmethod
    def type_name() -> str:
        return "shoal.ModelUpdate"


assert ctypes.sizeof(Pose) == 176
assert ctypes.sizeof(ClockTick) == 24
assert ctypes.sizeof(Scan) == 56 + 4 * MAX_BEAMS + 4
assert ctypes.sizeof(Estimate) == 48
assert ctypes.sizeof(ModelUpdate) == 72


class SlamParticles(ctypes.Structure):
    """`shoal.SlamParticles`: a followed robot's particles after a SLAM step."""

    _fields_ = [
        ("agent_id", ctypes.c_uint32),
        ("count", ctypes.c_uint32),
        ("tick", ctypes.c_uint64),
        ("sim_time", ctypes.c_double),
        ("xy", (ctypes.c_float * 2) * MAX_SHOWN_PARTICLES),
    ]

    @staticmethod
    def type_name() -> str:
        return "shoal.SlamParticles"


class SlamMap(ctypes.Structure):
    """`shoal.SlamMap`: a followed robot's coarse map (0 free, 100 occupied, 255 unknown)."""

    _fields_ = [
        ("agent_id", ctypes.c_uint32),
        ("width", ctypes.c_uint32),
        ("height", ctypes.c_uint32),
        ("cell_size", ctypes.c_float),
        ("origin", ctypes.c_float * 2),
        ("tick", ctypes.c_uint64),
        ("sim_time", ctypes.c_double),
        ("cells", ctypes.c_uint8 * (MAX_MAP_SIDE * MAX_MAP_SIDE)),
    ]

    @staticmethod
    def type_name() -> str:
        return "shoal.SlamMap"


class HelperProgress(ctypes.Structure):
    """`shoal.HelperProgress`: the newest tick a recorder or SLAM process has read."""

    _fields_ = [("tick", ctypes.c_uint64)]

    @staticmethod
    def type_name() -> str:
        return "shoal.HelperProgress"
