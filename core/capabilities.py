"""What a backend declares it can do, and the check the core makes before anything runs.

A provider states its backend's capabilities in its :class:`~agrisim.kinds.BackendSpec`; a
spec that states none gets the kind's defaults, which promise the least. The core refuses a
setting the chosen backend cannot honour with one line naming the backend, what it cannot do,
and the backends that can, before anything is built or written.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from agrisim.errors import UserError

if TYPE_CHECKING:
    from agrisim.kinds import BackendSpec

#: the segmentation modes: the paper's labels cut out by opacity ("Ours"), then EasySynth's (RepOpa)
SEG_MODES = ("texture", "repopa")


@dataclass(frozen=True)
class RendererCapabilities:
    """What a renderer draws."""

    seg_modes: frozenset[str] = field(default_factory=lambda: frozenset({"texture"}))
    """Segmentation modes it honours: ``texture`` (labels cut out by opacity, the paper's) and
    ``repopa`` (labels ignore opacity, EasySynth's)."""
    organ_labels: bool = False
    """One label per organ (``--labels organs``), not only one for the whole plant."""
    leaf_instances: bool = False
    """A leaf-instance image beside the labels."""
    soft_shadows: bool = False
    """Area lights sampled for soft shadows."""
    supersampling: bool = False
    """More than one RGB ray per pixel."""
    rerender: bool = False
    """Draws RGB alone from a saved scene (:meth:`Renderer.render_rgb`, ``agrisim render``)."""
    points: bool = False
    """Draws a point plant (``Scene.points``): every point a sphere of its size, with exact
    labels, depth and instances on the spheres."""
    lenses: bool = False
    """Draws through a lens's distortion (``CameraModel.distortion``): each pixel's own ray,
    labels and depth exact at the distorted positions."""
    radiance: bool = False
    """Keeps each view's linear radiance when its options' ``radiance`` is set (an imager
    makes its images from it)."""
    plants: bool = False
    """Tells a bench's plants apart: ``Frame.plants``, which plant each pixel shows."""


@dataclass(frozen=True)
class PhysicsCapabilities:
    """What a physics backend simulates."""

    dynamics: bool = False
    """Simulates dynamics (controllers, settling); without it the arms follow plans exactly."""


@dataclass(frozen=True)
class RigCapabilities:
    """What a rig's cell asks of the run."""

    room: str | None = None
    """The room drawn around it where ``[room] backend`` is not set (the turntable's ``cabinet``,
    symmetric about the stage's axis: its views are then the turned plant's exactly)."""


@dataclass(frozen=True)
class ReconstructorCapabilities:
    """What a reconstructor produces."""

    clouds: bool = True
    """A point cloud per label."""
    meshes: bool = False
    """A surface mesh per label."""
    needs_cuda: bool = False
    """Runs only with a CUDA GPU that PyTorch can use (refused elsewhere before anything runs)."""
    needs_hidden_robots: bool = False
    """Needs views without the arms in them (``--hide-robots``): the arms move between views,
    which a static scene model cannot explain."""
    folder: str | None = None
    """Writes files of its own into ``RUN/<folder>/`` (beside ``clouds/``)."""
    lenses: bool = False
    """Reads views through a lens's distortion (back-projects each pixel along its own ray)."""


@dataclass(frozen=True)
class SensorCapabilities:
    """What a depth sensor measures."""

    points: bool = False
    """Measures a point plant (``Scene.points``: spheres) as well as meshes."""
    range_m: tuple[float, float] = (0.0, float("inf"))
    """The depths it measures, m (its published operating range)."""


#: kind -> its capabilities type (kinds without one declare nothing)
CAPABILITIES: dict[str, type] = {
    "renderer": RendererCapabilities,
    "sensor": SensorCapabilities,
    "physics": PhysicsCapabilities,
    "reconstructor": ReconstructorCapabilities,
    "rig": RigCapabilities,
}


def describe(capabilities: object) -> str:
    """One line for ``agrisim plugins``: what is on, e.g. ``seg modes texture, repopa; organ labels``."""
    parts = []
    for name, value in vars(capabilities).items():
        if isinstance(value, frozenset):
            parts.append(f"{name.replace('_', ' ')} {', '.join(sorted(value)) or 'none'}")
        elif value is True:
            parts.append(name.replace("_", " "))
        elif isinstance(value, str):  # e.g. a rig's room
            parts.append(f"{name.replace('_', ' ')} {value}")
    return "; ".join(parts) or "none"


def check_renderer(
    spec: BackendSpec,
    renderers: Mapping[str, BackendSpec],
    seg_modes: Iterable[str],
    labels: str,
    points: bool = False,
    lens: bool = False,
    radiance: bool = False,
    bench: bool = False,
) -> None:
    """Refuse rendering with ``spec`` in ``seg_modes`` with ``labels`` (and a point plant, with
    ``points``; through a distorting lens, with ``lens``; keeping linear radiance for an imager,
    with ``radiance``; a bench of plants, with ``bench``) if it cannot do them.

    ``renderers`` are all installed renderers, to name those that could."""

    def missing(caps: RendererCapabilities) -> list[str]:
        out = [f"segmentation mode {m!r}" for m in seg_modes if m not in caps.seg_modes]
        if labels == "organs" and not caps.organ_labels:
            out.append("organ labels")
        if points and not getattr(caps, "points", False):
            out.append("point plants")
        if lens and not getattr(caps, "lenses", False):
            out.append("through a lens's distortion")
        if radiance and not getattr(caps, "radiance", False):
            out.append("linear radiance for an imager")
        if bench and not getattr(caps, "plants", False):
            out.append("a bench's plants apart")
        return out

    lacking = missing(spec.capabilities)
    if lacking:
        able = [name for name, other in renderers.items() if not missing(other.capabilities)]
        offer = f"; renderers that can: {', '.join(able)}" if able else ""
        modes = ", ".join(sorted(spec.capabilities.seg_modes))
        raise UserError(
            f"renderer backend {spec.name!r} cannot draw {' or '.join(lacking)} "
            f"(it does segmentation modes {modes}{', organ labels' if spec.capabilities.organ_labels else ', no organ labels'})"
            f"{offer}"
        )


def check_sensor(spec: BackendSpec, sensors: Mapping[str, BackendSpec], points: bool = False) -> None:
    """Refuse measuring a point plant (``points``) with a sensor ``spec`` that cannot see one,
    naming the sensors that can (``sensors``: all installed)."""
    if points and not spec.capabilities.points:
        able = [name for name, other in sensors.items() if other.capabilities.points]
        raise UserError(
            f"depth sensor {spec.name!r} cannot see point plants (spheres); sensors that can: {', '.join(able) or 'none'}"
        )


def cuda_usable() -> str | None:
    """None when PyTorch is installed and sees a CUDA GPU, else why not (one line)."""
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        return "PyTorch is not installed"
    import torch

    if not torch.cuda.is_available():
        return "PyTorch sees no CUDA GPU here"
    return None


def check_reconstructor(spec: BackendSpec, hide_robots: bool, lens: bool = False) -> None:
    """Refuse reconstructing with ``spec`` where it cannot run: without a CUDA GPU when it needs
    one, on views with the arms in them when it needs them hidden, or on views through a
    distorting lens (``lens``) when it reads pinholes only."""
    caps = spec.capabilities
    if lens and not getattr(caps, "lenses", False):
        raise UserError(
            f"reconstructor {spec.name!r} reads pinhole views only and this camera has a distorting lens; "
            "use the pointcloud reconstructor, or a camera without distortion"
        )
    if getattr(caps, "needs_hidden_robots", False) and not hide_robots:
        raise UserError(
            f"reconstructor {spec.name!r} needs views without the arms in them (they move between views): "
            "render the run with --hide-robots"
        )
    if getattr(caps, "needs_cuda", False):
        why = cuda_usable()
        if why is not None:
            raise UserError(f"reconstructor {spec.name!r} needs a CUDA GPU: {why}")
