"""Lens distortion as OpenCV models it: where a ray lands on the image (``distort``) and which ray
a point of the image sees (``undistort``), for renderers that trace each pixel's own ray.

Two models, in normalised camera coordinates (x, y) = (X / Z, Y / Z):

* ``brown-conrady``: OpenCV's default ``(k1, k2, p1, p2, k3)`` (ROS's ``plumb_bob``, COLMAP's
  ``OPENCV`` with k3 = 0, nerfstudio's ``OPENCV``);
* ``fisheye``: Kannala-Brandt ``(k1, k2, k3, k4)`` as ``cv2.fisheye`` has it (ROS's
  ``equidistant``, COLMAP's and nerfstudio's ``OPENCV_FISHEYE``): the angle from the axis,
  theta, lands at radius theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8).

The inverse has no closed form; Newton's method from the distorted point converges in a few
steps on any lens that does not fold (:func:`check_unfolded` refuses those). The functions use
nothing but arithmetic, so they run on NumPy arrays and, unchanged, on Dr.Jit's inside a
renderer's kernel, where a path tracer's samples fall anywhere in a pixel. OpenCV's own
``projectPoints`` and ``undistortPoints`` check them in the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from agrisim.errors import UserError

Model = Literal["brown-conrady", "fisheye"]
#: coefficient names of each model, in OpenCV's order
COEFFICIENTS: dict[str, tuple[str, ...]] = {
    "brown-conrady": ("k1", "k2", "p1", "p2", "k3"),
    "fisheye": ("k1", "k2", "k3", "k4"),
}
#: Newton steps of the inverse: enough for 1e-12 on every lens check_unfolded lets through
NEWTON_STEPS = 12


@dataclass(frozen=True)
class Distortion:
    """A lens's distortion: ``model`` and its ``coefficients`` in OpenCV's order."""

    model: Model
    coefficients: tuple[float, ...]

    def __post_init__(self) -> None:
        names = COEFFICIENTS.get(self.model)
        if names is None:
            raise UserError(f"lens model {self.model!r} is unknown; allowed: {', '.join(COEFFICIENTS)}")
        if len(self.coefficients) != len(names):
            raise UserError(
                f"lens model {self.model!r} takes {len(names)} coefficients ({', '.join(names)}), "
                f"got {len(self.coefficients)}"
            )
        if not all(math.isfinite(c) for c in self.coefficients):
            raise UserError(f"lens coefficients must be finite numbers, got {list(self.coefficients)}")

    @property
    def opencv(self) -> np.ndarray:
        """The coefficients as OpenCV's ``distCoeffs`` (or ``D`` of ``cv2.fisheye``)."""
        return np.asarray(self.coefficients, np.float64)

    def as_dict(self) -> dict[str, Any]:
        return {"model": self.model, **dict(zip(COEFFICIENTS[self.model], self.coefficients, strict=True))}

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> Distortion:
        model = doc.get("model")
        names = COEFFICIENTS.get(str(model), ())
        return cls(model, tuple(float(doc.get(n, 0.0)) for n in names))  # type: ignore[arg-type]

    def distort(self, x: Any, y: Any) -> tuple[Any, Any]:
        """Where the ray of slopes (x, y) lands, in distorted normalised coordinates."""
        if self.model == "fisheye":
            r = _sqrt(x * x + y * y)
            theta = _atan(r)
            scale = _where(r > 1e-12, _fisheye_radius(self.coefficients, theta) / _max(r, 1e-12), 1.0)
            return x * scale, y * scale
        k1, k2, p1, p2, k3 = self.coefficients
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        return (
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        )

    def undistort(self, xd: Any, yd: Any) -> tuple[Any, Any]:
        """The slopes (x, y) of the ray that lands at distorted normalised (xd, yd)."""
        if self.model == "fisheye":
            rd = _sqrt(xd * xd + yd * yd)
            theta = rd  # theta_d(theta) is near theta: start there
            for _ in range(NEWTON_STEPS):
                f = _fisheye_radius(self.coefficients, theta) - rd
                theta = theta - f / _fisheye_slope(self.coefficients, theta)
            scale = _where(rd > 1e-12, _tan(theta) / _max(rd, 1e-12), 1.0)
            return xd * scale, yd * scale
        k1, k2, p1, p2, k3 = self.coefficients
        x, y = xd, yd
        for _ in range(NEWTON_STEPS):
            r2 = x * x + y * y
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            slope = 2.0 * (k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2))  # d radial / d r2, times 2
            fx = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd
            fy = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - yd
            a = radial + x * x * slope + 2.0 * p1 * y + 6.0 * p2 * x  # the Jacobian [[a, b], [c, d]]
            b = x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y
            d = radial + y * y * slope + 6.0 * p1 * y + 2.0 * p2 * x
            det = a * d - b * b  # (c == b)
            x = x - (d * fx - b * fy) / det
            y = y - (a * fy - b * fx) / det
        return x, y

    def radial(self, r: np.ndarray) -> np.ndarray:
        """The distorted radius of an undistorted one along the x axis (no tangential part)."""
        xd, _ = self.distort(np.asarray(r, np.float64), np.zeros_like(r, np.float64))
        return np.asarray(xd)


def check_unfolded(lens: Distortion, reach: float, what: str = "camera") -> None:
    """Refuse a lens whose radial function turns back before it covers the image: beyond that
    radius two rays land on one pixel and some pixels see none. ``reach`` is the farthest
    distorted normalised radius of the image (its far corner)."""
    top = 1.55 if lens.model == "fisheye" else 8.0  # (fisheye: angles up to 89 degrees)
    r = np.linspace(0.0, np.tan(top) if lens.model == "fisheye" else top, 20001)[1:]
    rd = lens.radial(r)
    rising = np.diff(rd) > 0
    covered = rd[1:] >= reach
    first_fall = int(np.argmin(rising)) if not rising.all() else len(rising)
    if not covered[:first_fall].any():
        turn = rd[first_fall] if first_fall < len(rd) else rd[-1]
        raise UserError(
            f"{what}: the lens {lens.as_dict()} folds the image: its distorted radius peaks at {turn:.3f} "
            f"(normalised), short of the image's corner at {reach:.3f}; allowed: coefficients whose "
            "distorted radius grows across the whole image"
        )


def _fisheye_radius(k: tuple[float, ...], theta: Any) -> Any:
    t2 = theta * theta
    return theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))


def _fisheye_slope(k: tuple[float, ...], theta: Any) -> Any:
    t2 = theta * theta
    return 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])))


# the few functions beyond arithmetic, for NumPy arrays and Dr.Jit's alike
def _is_numpy(x: Any) -> bool:
    return isinstance(x, (np.ndarray, np.generic, float, int))


def _sqrt(x: Any) -> Any:
    if _is_numpy(x):
        return np.sqrt(x)
    import drjit as dr

    return dr.sqrt(x)


def _atan(x: Any) -> Any:
    if _is_numpy(x):
        return np.arctan(x)
    import drjit as dr

    return dr.atan(x)


def _tan(x: Any) -> Any:
    if _is_numpy(x):
        return np.tan(x)
    import drjit as dr

    return dr.tan(x)


def _max(x: Any, floor: float) -> Any:
    if _is_numpy(x):
        return np.maximum(x, floor)
    import drjit as dr

    return dr.maximum(x, floor)


def _where(cond: Any, a: Any, b: Any) -> Any:
    if _is_numpy(cond):
        return np.where(cond, a, b)
    import drjit as dr

    return dr.select(cond, a, b)
