"""The run directory's layout: where each file of a run lives, defined once.

::

    OUT/run.json               what ran and how far it got (status, per-setpoint results)
    OUT/cameras.json           intrinsics and the pose of every complete frame
    OUT/<folder>/<frame>.png   folder: rgb, labels, labels_vis, depth, instances, plants (a bench's)
    OUT/depth/<frame>.exr      float32 planar depth in metres (--depth-format exr or both)
    OUT/masks/<frame>.png      nerfstudio's masks (255 = plant)
    OUT/clouds/<label>.ply     reconstructed clouds; <label>_mesh.ply for surfaces; clouds/plant_01/... a bench's
    OUT/metrics.json           accuracy against the true plant
    OUT/transforms.json        the nerfstudio export
    OUT/scene/plant.glb        the plant as rendered, with its label textures
    OUT/scene/lab.glb          the whole scene as rendered: room, clutter, table, pot, plant,
                               lights and the arms' link meshes (``agrisim render`` reads it)
    OUT/link_poses/<frame>.json  world_T_link of every arm link when the frame was rendered
    OUT/trajectories/<frame>.json  the arm's move to that setpoint: planner waypoints, the
                               planned and the executed joint trajectory in simulated time
    OUT/radiance/<frame>.exr   linear RGB radiance (float32), when the renderer was asked for it
    OUT/raw/<frame>.png        the imager's raw Bayer frame (uint16 digital numbers, RGGB), when kept
    OUT/recording.rrd          the Rerun recording (unless --rrd puts it elsewhere)
    OUT/coco/annotations.json  the COCO export (agrisim export coco)
    OUT/rosbag/                the ROS 2 bag export (agrisim export rosbag)
    OUT/colmap/                COLMAP's model of the views and its scores (agrisim colmap)

The dataset writer writes it; ``--resume``, ``agrisim recon``, the exports and ``agrisim compare``
read it, all through these names.
"""

from __future__ import annotations

from pathlib import Path

RUN_JSON = "run.json"
CAMERAS_JSON = "cameras.json"
METRICS_JSON = "metrics.json"
TRANSFORMS_JSON = "transforms.json"
RECORDING = "recording.rrd"
PLANT_GLB = Path("scene") / "plant.glb"
#: a point plant as drawn (world coordinates, labels, instances, point size)
PLANT_POINTS = Path("scene") / "plant_points.ply"
SCENE_GLB = Path("scene") / "lab.glb"
LINK_POSES = "link_poses"
TRAJECTORIES = "trajectories"
RADIANCE = "radiance"
CLOUDS = "clouds"
MASKS = "masks"
ROSBAG = "rosbag"
COLMAP = "colmap"
#: what the run's depth sensor measured, uint16 mm on the colour camera's pixels (not with the
#: exact sensor, whose measurement is ``depth/``)
DEPTH_SENSOR = "depth_sensor"
#: the imager's raw Bayer frames (``imager.raw``)
RAW = "raw"
#: which plant of a bench each pixel shows (uint16; 0: none, k: the bench's k-th plant)
PLANTS = "plants"
#: the image folders of a frame, each holding ``<frame>.png``
FRAME_FOLDERS = ("rgb", "labels", "labels_vis", "depth", "instances", PLANTS, DEPTH_SENSOR, RAW)
#: the folders every complete rendered frame has (instances only where leaves are numbered)
REQUIRED_FOLDERS = ("rgb", "labels", "depth")


def image(root: Path, folder: str, frame: str) -> Path:
    """``root/<folder>/<frame>.png``."""
    return Path(root) / folder / f"{frame}.png"


def depth_exr(root: Path, frame: str) -> Path:
    """The exact depth of ``frame``: ``root/depth/<frame>.exr``."""
    return Path(root) / "depth" / f"{frame}.exr"


def has_image(root: Path, folder: str, frame: str) -> bool:
    """Does ``frame`` have its image of ``folder`` (depth: as PNG or as EXR)?"""
    return image(root, folder, frame).is_file() or (folder == "depth" and depth_exr(root, frame).is_file())


def cloud(root: Path, label: str, plant: str = "") -> Path:
    """The reconstructed cloud of ``label``: ``root/clouds/[<plant>/]<label>.ply`` (a bench's ``plant``'s own)."""
    return Path(root) / CLOUDS / plant / f"{label}.ply"


def surface(root: Path, label: str, plant: str = "") -> Path:
    """The reconstructed surface of ``label``: ``root/clouds/[<plant>/]<label>_mesh.ply`` (a bench's ``plant``'s)."""
    return Path(root) / CLOUDS / plant / f"{label}_mesh.ply"


def radiance(root: Path, frame: str) -> Path:
    """The linear radiance of ``frame``: ``root/radiance/<frame>.exr``."""
    return Path(root) / RADIANCE / f"{frame}.exr"


def link_poses(root: Path, frame: str) -> Path:
    """The arms' link poses of ``frame``: ``root/link_poses/<frame>.json``."""
    return Path(root) / LINK_POSES / f"{frame}.json"


def trajectory(root: Path, frame: str) -> Path:
    """The arm's move to the setpoint of ``frame``: ``root/trajectories/<frame>.json``."""
    return Path(root) / TRAJECTORIES / f"{frame}.json"
