"""Near-infrared reflectance of the scene's surfaces, at about 850 nm where the active depth
cameras (Azure Kinect, RealSense D415/D435 projectors) illuminate.

A material states its own (:attr:`agrisim.scene.model.Material.nir`): the procedural species'
leaves from their own PROSPECT-D leaf at 850 nm (0.43-0.54), their stems and the Helios crops'
organs from the values below. Any other material is estimated from its visible
albedo: a fair guess for paint, plastic and wood, which reflect about as much in the near
infrared as in the visible, and a poor one for living tissue, which is why plants set theirs.

Values: green leaves reflect 40-55% between 750 and 1,000 nm, the "NIR plateau" of leaf spectra
(mesophyll scattering; Jacquemoud & Ustin, *Leaf Optical Properties*, Cambridge University
Press, 2019, ch. 2 and 7); green stems somewhat less, bark and woody stems 30-40%, petals
50-70% whatever their colour. Each is one typical number, not a spectrum.
"""

from __future__ import annotations

import numpy as np

from agrisim.scene.colour import srgb_to_linear
from agrisim.scene.model import Material

#: a green leaf's reflectance on the NIR plateau
LEAF = 0.50
#: a green (herbaceous) stem
STEM = 0.40
#: bark, woody stems
WOOD = 0.35
#: petals, whatever their visible colour
PETAL = 0.60


def visible_albedo(material: Material) -> float:
    """Mean linear albedo of ``material`` over its opaque texels (the colour factor times the
    texture; the colour alone without one), averaged over R, G and B."""
    colour = np.asarray(material.color, np.float64)[:3]
    if material.albedo is None:
        return float(colour.mean())
    rgba = np.asarray(material.albedo)
    kept = rgba[..., 3] >= 128 if material.cuts else np.ones(rgba.shape[:2], bool)
    texels = rgba[kept][:, :3] if kept.any() else rgba.reshape(-1, 4)[:, :3]
    return float((srgb_to_linear(texels / 255.0).mean(axis=0) * colour).mean())


def nir_reflectance(material: Material) -> float:
    """The material's near-infrared reflectance: its own, else its visible albedo, in [0, 1]."""
    value = material.nir if material.nir is not None else visible_albedo(material)
    return float(np.clip(value, 0.0, 1.0))
