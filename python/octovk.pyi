"""octovk: an OctoMap-compatible occupancy octree on a Vulkan device (type stub; the module is
python/src/*.cpp, and python/tests/test_api.py checks that this stub names what it binds)."""

import enum
import os
from typing import Any, ClassVar, Iterator, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

# Arrays: numpy arrays, torch CPU tensors or any object with the buffer protocol or __dlpack__.
ArrayLike = Any
Vector3 = Union[Sequence[float], ArrayLike]
PoseLike = Union[None, "Pose", ArrayLike, Tuple[Vector3, Sequence[float]]]
PathLike = Union[str, bytes, os.PathLike]
FloatArray = npt.NDArray[np.float32]
ByteArray = npt.NDArray[np.uint8]

__version__: str  # the CMake project's version

class ErrorCode:
    """A pybind11 enum (int(code) gives its value)."""
    NO_DEVICE: ClassVar[ErrorCode]  # 0
    MISSING_FEATURE: ClassVar[ErrorCode]  # 1
    INVALID_ARGUMENT: ClassVar[ErrorCode]  # 2
    OUT_OF_DEVICE_MEMORY: ClassVar[ErrorCode]  # 3
    VULKAN: ClassVar[ErrorCode]  # 4
    IO: ClassVar[ErrorCode]  # 5
    FORMAT: ClassVar[ErrorCode]  # 6
    OUT_OF_HOST_MEMORY: ClassVar[ErrorCode]  # 7
    INTERNAL: ClassVar[ErrorCode]  # 8
    @property
    def name(self) -> str: ...
    @property
    def value(self) -> int: ...
    def __int__(self) -> int: ...

class Error(RuntimeError):
    code: ErrorCode
    message: str
    scan: int
    detail: str

class NoDeviceError(Error): ...
class MissingFeatureError(Error): ...
class InvalidArgumentError(Error, ValueError): ...
class OutOfDeviceMemoryError(Error, MemoryError): ...
class VulkanError(Error): ...
class IoError(Error, OSError): ...
class FormatError(Error): ...
class OutOfHostMemoryError(Error, MemoryError): ...
class InternalError(Error): ...

class CellState(enum.IntEnum):
    """Map.search() returns these values as uint8: `state == CellState.FREE` compares them."""
    UNKNOWN = 0
    FREE = 1
    OCCUPIED = 2

class CastRayBackend:
    """How castRay is answered on the device."""
    AUTO: ClassVar[CastRayBackend]  # 0
    WALK: ClassVar[CastRayBackend]  # 1
    RAY_TRACING: ClassVar[CastRayBackend]  # 2
    RAY_QUERY: ClassVar[CastRayBackend]  # 3
    RT_PIPELINE: ClassVar[CastRayBackend]  # 4
    @property
    def name(self) -> str: ...
    @property
    def value(self) -> int: ...
    def __int__(self) -> int: ...

class ScanRays:
    """How a scan's rays find their cells."""
    WALK: ClassVar[ScanRays]  # 1
    RAY_TRACING: ClassVar[ScanRays]  # 2
    RAY_QUERY: ClassVar[ScanRays]  # 3
    RT_PIPELINE: ClassVar[ScanRays]  # 4
    @property
    def name(self) -> str: ...
    @property
    def value(self) -> int: ...
    def __int__(self) -> int: ...

class DeviceInfo:
    name: str
    type: str
    driver: str
    index: int
    memory_bytes: int
    ray_query: bool
    ray_tracing_pipeline: bool
    ray_query_enabled: bool

class Context:
    def __init__(self, selector: Union[None, int, str] = None, enable_validation: bool = False,
                 enable_ray_query: bool = True, *,
                 device: Union[None, int, str] = None,  # deprecated: selector
                 validation: Optional[bool] = None,  # deprecated: enable_validation
                 ray_query: Optional[bool] = None  # deprecated: enable_ray_query
                 ) -> None: ...
    @property
    def device(self) -> DeviceInfo: ...

def devices() -> list[DeviceInfo]: ...
def cpu_driver_threads() -> tuple[str, bool]: ...
def default_context() -> Context: ...
def validation_message_count() -> int: ...
def _last_input_address() -> int: ...

class Pose:
    def __init__(self, translation: Vector3 = (0, 0, 0),
                 rotation: Sequence[float] = (0, 0, 0, 1)) -> None: ...
    @staticmethod
    def from_matrix(matrix: ArrayLike) -> Pose: ...
    @property
    def translation(self) -> FloatArray: ...
    @property
    def rotation(self) -> FloatArray: ...
    def matrix(self) -> npt.NDArray[np.float64]: ...
    def inverse(self) -> Pose: ...
    def transform(self, point: Vector3) -> FloatArray: ...

class StageTimes:
    upload_ms: float
    ray_keys_ms: float
    classify_ms: float
    tree_update_ms: float
    prune_ms: float
    leaf_boxes_ms: float
    @property
    def total_ms(self) -> float: ...

class ScanStats:
    ticket: int
    points: int
    skipped_nonfinite: int
    skipped_outside: int
    skipped_no_depth: int
    free_cells: int
    occupied_cells: int
    aborted_cells: int
    nodes: int
    cell_set_attempts: int
    tile_groups: int
    wall_ms: float
    device: StageTimes

class DeviceBytes:
    pool: int
    leaf_boxes: int
    scratch: int
    queries: int
    changes: int
    distance_fields: int
    @property
    def total(self) -> int: ...

class CastRayInfo:
    backend: CastRayBackend
    builds: int
    last_build_ms: float
    occupied_boxes: int
    device_bytes: int
    cap_fallbacks: int

class Map:
    def __init__(self, resolution: float = 0.1, *, prob_hit: float = 0.7, prob_miss: float = 0.4,
                 clamping_min: float = 0.1192, clamping_max: float = 0.971,
                 occupancy_threshold: float = 0.5, max_nodes: int = 0,
                 max_device_bytes: int = 0,
                 cast_ray_backend: CastRayBackend = CastRayBackend.AUTO,
                 scan_rays: ScanRays = ScanRays.WALK,
                 context: Optional[Context] = None) -> None: ...
    # Returns the class of the file's tree type: Map, ColorMap or StampedMap.
    @staticmethod
    def read(path: PathLike, *, context: Optional[Context] = None,
             max_device_bytes: int = 0) -> Map: ...
    # store: an SQLite file or a PostgreSQL URI; a snapshot of the map's last committed scan.
    @staticmethod
    def open(store: Union[str, PathLike], map: str = "default", *,
             context: Optional[Context] = None, max_device_bytes: int = 0) -> Map: ...
    def write(self, path: PathLike) -> None: ...
    # points: float32 (N, 3), (H, W, 3), or (N, 4) with x, y, z first (copied with copy=True).
    # max_range: the deprecated name of max_range_m.
    def insert_point_cloud(self, points: ArrayLike, origin: Vector3, pose: PoseLike = None,
                           max_range_m: float = -1.0, discretize: bool = False, *,
                           copy: bool = False, max_range: Optional[float] = None
                           ) -> ScanStats: ...
    def submit_point_cloud(self, points: ArrayLike, origin: Vector3, pose: PoseLike = None,
                           max_range_m: float = -1.0, discretize: bool = False, *,
                           copy: bool = False, max_range: Optional[float] = None) -> int: ...
    # depth: float32 or uint16 (H, W) or (1, H, W).
    def insert_depth_image(self, depth: ArrayLike, fx: float, fy: float, cx: float, cy: float,
                           depth_scale: float, pose: PoseLike = None, max_range_m: float = -1.0,
                           discretize: bool = False, *, max_range: Optional[float] = None
                           ) -> ScanStats: ...
    def submit_depth_image(self, depth: ArrayLike, fx: float, fy: float, cx: float, cy: float,
                           depth_scale: float, pose: PoseLike = None, max_range_m: float = -1.0,
                           discretize: bool = False, *, max_range: Optional[float] = None
                           ) -> int: ...
    def flush(self) -> None: ...
    def finished(self, ticket: int) -> bool: ...
    def take_scan_stats(self) -> list[ScanStats]: ...
    # Properties never wait for the device nor raise; methods that read the map wait for the
    # submitted scans first and may raise a scan's error.
    @property
    def scans_in_flight(self) -> int: ...
    # Results: one per point ((N,) or (H, W)); torch tensors when the input is one.
    def search(self, points: ArrayLike,
               out: Optional[Tuple[ArrayLike, ArrayLike, ArrayLike]] = None, *,
               copy: bool = False) -> Tuple[ArrayLike, ArrayLike, ArrayLike]: ...
    def cast_rays(self, origins: Union[ArrayLike, Vector3], directions: ArrayLike,
                  max_range_m: float = -1.0, ignore_unknown: bool = False,
                  out: Optional[Tuple[ArrayLike, ArrayLike]] = None, *,
                  copy: bool = False, max_range: Optional[float] = None
                  ) -> Tuple[ArrayLike, ArrayLike]: ...
    def leaves_in_box(self, min: Vector3, max: Vector3, occupied_only: bool = False
                      ) -> Tuple[FloatArray, FloatArray, FloatArray]: ...
    def leaves(self) -> Tuple[FloatArray, FloatArray, FloatArray]: ...
    def clear_box(self, min: Vector3, max: Vector3) -> None: ...
    def keep_box(self, min: Vector3, max: Vector3) -> None: ...
    def compact(self) -> None: ...
    def enable_change_detection(self, enable: bool) -> None: ...
    def is_change_detection_enabled(self) -> bool: ...
    def reset_change_detection(self) -> None: ...
    def num_changes_detected(self) -> int: ...
    def changed_keys(self) -> Tuple[npt.NDArray[np.uint16], ByteArray]: ...
    def node_count(self) -> int: ...
    def leaf_count(self) -> int: ...
    # The total, an int (C++'s deviceBytes()); its .pool, ... fields are deprecated.
    def device_bytes(self) -> int: ...
    def device_bytes_by_use(self) -> DeviceBytes: ...
    def cast_ray_info(self) -> CastRayInfo: ...
    def spill_tiles(self, to_file: bool = True) -> None: ...
    def spilled_tiles(self) -> int: ...
    def trim(self) -> None: ...
    @property
    def context(self) -> Context: ...
    @property
    def resolution(self) -> float: ...
    @property
    def prob_hit(self) -> float: ...
    @property
    def prob_miss(self) -> float: ...
    @property
    def clamping_min(self) -> float: ...
    @property
    def clamping_max(self) -> float: ...
    @property
    def occupancy_threshold(self) -> float: ...
    @property
    def max_device_bytes(self) -> int: ...

# colors: uint8 (N, 3) per point ((H, W, 3) for an organised cloud or a depth image).
ColorFold = Literal["average", "integrate"]

class ColorMap(Map):
    """ColorOcTree: a Map whose nodes hold a colour (white: none yet)."""
    def __init__(self, resolution: float = 0.1, *, prob_hit: float = 0.7, prob_miss: float = 0.4,
                 clamping_min: float = 0.1192, clamping_max: float = 0.971,
                 occupancy_threshold: float = 0.5, max_nodes: int = 0,
                 max_device_bytes: int = 0,
                 cast_ray_backend: CastRayBackend = CastRayBackend.AUTO,
                 scan_rays: ScanRays = ScanRays.WALK,
                 context: Optional[Context] = None) -> None: ...
    @staticmethod
    def read(path: PathLike, *, context: Optional[Context] = None,
             max_device_bytes: int = 0) -> ColorMap: ...
    def insert_point_cloud(self, points: ArrayLike, origin: Vector3, pose: PoseLike = None,
                           max_range_m: float = -1.0, discretize: bool = False, *,
                           colors: Optional[ArrayLike] = None, color_fold: ColorFold = "average",
                           copy: bool = False, max_range: Optional[float] = None
                           ) -> ScanStats: ...
    def submit_point_cloud(self, points: ArrayLike, origin: Vector3, pose: PoseLike = None,
                           max_range_m: float = -1.0, discretize: bool = False, *,
                           colors: Optional[ArrayLike] = None, color_fold: ColorFold = "average",
                           copy: bool = False, max_range: Optional[float] = None) -> int: ...
    def insert_depth_image(self, depth: ArrayLike, fx: float, fy: float, cx: float, cy: float,
                           depth_scale: float, pose: PoseLike = None, max_range_m: float = -1.0,
                           discretize: bool = False, *, colors: Optional[ArrayLike] = None,
                           color_fold: ColorFold = "average", max_range: Optional[float] = None
                           ) -> ScanStats: ...
    def submit_depth_image(self, depth: ArrayLike, fx: float, fy: float, cx: float, cy: float,
                           depth_scale: float, pose: PoseLike = None, max_range_m: float = -1.0,
                           discretize: bool = False, *, colors: Optional[ArrayLike] = None,
                           color_fold: ColorFold = "average", max_range: Optional[float] = None
                           ) -> int: ...
    # uint8 r, g, b per point ((N, 3) or (H, W, 3)); white where search finds no node.
    def colors(self, points: ArrayLike, *, copy: bool = False) -> ArrayLike: ...

class StampedMap(Map):
    """OcTreeStamped: a Map whose nodes hold a time stamp in whole seconds."""
    def __init__(self, resolution: float = 0.1, *, prob_hit: float = 0.7, prob_miss: float = 0.4,
                 clamping_min: float = 0.1192, clamping_max: float = 0.971,
                 occupancy_threshold: float = 0.5, max_nodes: int = 0,
                 max_device_bytes: int = 0,
                 cast_ray_backend: CastRayBackend = CastRayBackend.AUTO,
                 scan_rays: ScanRays = ScanRays.WALK,
                 context: Optional[Context] = None) -> None: ...
    @staticmethod
    def read(path: PathLike, *, context: Optional[Context] = None,
             max_device_bytes: int = 0) -> StampedMap: ...
    # stamp: whole seconds, 0 to 2**32 - 1; None: int(time.time()).
    def insert_point_cloud(self, points: ArrayLike, origin: Vector3, pose: PoseLike = None,
                           max_range_m: float = -1.0, discretize: bool = False, *,
                           stamp: Optional[int] = None, copy: bool = False,
                           max_range: Optional[float] = None) -> ScanStats: ...
    def submit_point_cloud(self, points: ArrayLike, origin: Vector3, pose: PoseLike = None,
                           max_range_m: float = -1.0, discretize: bool = False, *,
                           stamp: Optional[int] = None, copy: bool = False,
                           max_range: Optional[float] = None) -> int: ...
    def insert_depth_image(self, depth: ArrayLike, fx: float, fy: float, cx: float, cy: float,
                           depth_scale: float, pose: PoseLike = None, max_range_m: float = -1.0,
                           discretize: bool = False, *, stamp: Optional[int] = None,
                           max_range: Optional[float] = None) -> ScanStats: ...
    def submit_depth_image(self, depth: ArrayLike, fx: float, fy: float, cx: float, cy: float,
                           depth_scale: float, pose: PoseLike = None, max_range_m: float = -1.0,
                           discretize: bool = False, *, stamp: Optional[int] = None,
                           max_range: Optional[float] = None) -> int: ...
    def degrade_outdated(self, threshold_s: int, now: Optional[int] = None) -> None: ...
    # uint32 per point ((N,) or (H, W); an int64 tensor for torch); 0 where no node is found.
    def stamps(self, points: ArrayLike, *, copy: bool = False) -> ArrayLike: ...
    def last_update_time(self) -> int: ...

class DistanceField:
    OUTSIDE: ClassVar[float]  # -1.0
    OUTSIDE_CELLS: ClassVar[int]  # 0xFFFFFFFF
    NO_OBSTACLE_CELLS: ClassVar[int]  # 0xFFFFFFFE
    def __init__(self, map: Map, min: Optional[Vector3] = None, max: Optional[Vector3] = None,
                 *, max_distance_m: float = 2.0, treat_unknown_as_occupied: bool = True,
                 max_distance: Optional[float] = None  # deprecated: max_distance_m
                 ) -> None: ...
    def update(self) -> None: ...
    # Points as Map.search takes them; torch tensors in, torch tensors out (squared_cells int64).
    def distances(self, points: ArrayLike, *, copy: bool = False
                  ) -> Tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike]: ...
    def clearances(self, spheres: ArrayLike, *, copy: bool = False
                   ) -> Tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike]: ...
    def download(self) -> Tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint32]]: ...
    def torch_distances(self, points: Any) -> Any: ...  # torch.Tensor in, torch.Tensor out
    @staticmethod
    def autograd_function() -> Any: ...  # a torch.autograd.Function subclass
    @property
    def size(self) -> Tuple[int, int, int]: ...
    @property
    def min_key(self) -> Tuple[int, int, int]: ...
    @property
    def max_distance_m(self) -> float: ...
    @property
    def max_distance(self) -> float: ...  # deprecated: max_distance_m
    @property
    def treat_unknown_as_occupied(self) -> bool: ...
    def device_bytes(self) -> int: ...
    @property
    def last_update_ms(self) -> float: ...
    @property
    def map(self) -> Map: ...


class StoredMap:
    """A map of a store that scans are inserted into, each one committed."""
    @staticmethod
    def open(store: Union[str, PathLike], map: str = "default", *,
             resolution: Optional[float] = None, prob_hit: float = 0.7, prob_miss: float = 0.4,
             clamping_min: float = 0.1192, clamping_max: float = 0.971,
             occupancy_threshold: float = 0.5, tree_type: str = "OcTree",
             context: Optional[Context] = None, max_device_bytes: int = 0) -> StoredMap: ...
    def insert_point_cloud(self, points: ArrayLike, origin: Vector3, pose: PoseLike = None,
                           max_range_m: float = -1.0, discretize: bool = False, *,
                           colors: Optional[ArrayLike] = None, color_fold: str = "average",
                           stamp: Optional[int] = None, source: str = "python",
                           scan: Optional[int] = None, copy: bool = False) -> ScanStats: ...
    # Map, ColorMap or StampedMap: the class of the map's tree type.
    def snapshot(self, *, max_device_bytes: int = 0) -> Map: ...
    @property
    def tree_type(self) -> str: ...
    @property
    def last_seq(self) -> int: ...
    @property
    def name(self) -> str: ...
    @property
    def resolution(self) -> float: ...

class StoreFollower:
    """A map of a store followed while writers commit: poll() reads only what changed."""
    def __init__(self, store: Union[str, PathLike], map: str = "default") -> None: ...
    # None when nothing was committed since the last poll; else {"seq": int, "changed":
    # float64 (N, 6) tile boxes min x, y, z, max x, y, z in metres, "dropped": the same,
    # "bytes_read": int}.
    def poll(self) -> Optional[dict]: ...
    def updates(self, interval_s: float = 0.5,
                until_seq: Optional[int] = None) -> "_StoreUpdates": ...
    def map(self, *, context: Optional[Context] = None, max_device_bytes: int = 0) -> Map: ...
    @property
    def seq(self) -> int: ...
    @property
    def tree_type(self) -> str: ...
    @property
    def resolution(self) -> float: ...
    @property
    def tile_depth(self) -> int: ...

class _StoreUpdates(Iterator[dict]): ...

def read_scan_graph(path: PathLike) -> list[Tuple[FloatArray, Pose]]: ...
def graph2tree_sensor_origin(pose: Pose) -> FloatArray: ...
def read_tum_sequence(dir: PathLike, max_time_difference_s: float = 0.02, *,
                      max_time_difference: Optional[float] = None  # deprecated
                      ) -> list[Tuple[float, str, Pose]]: ...
def read_depth_png(path: PathLike) -> npt.NDArray[np.uint16]: ...
# The finest-depth key helpers (C++'s keyToCoord / coordToKey), vectorised over (..., 3).
def key_to_coord(resolution: float, keys: ArrayLike) -> ArrayLike: ...
def coord_to_key(resolution: float, coords: ArrayLike) -> ArrayLike: ...
