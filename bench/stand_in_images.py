"""Empty stand-ins for the images of a saved run carried without them: ``agrisim render`` (and
``bench/splat_plant.py train --draw``) check that the run's frames are complete (rgb, labels,
depth), not what the files hold, and draw everything they use from the saved scene.

    python bench/stand_in_images.py RUN [RUN ...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

for run in map(Path, sys.argv[1:]):
    for folder in ("rgb", "labels", "depth"):
        (run / folder).mkdir(exist_ok=True)
        for frame in json.loads((run / "run.json").read_text())["frames_complete"]:
            image = run / folder / f"{frame}.png"
            if not image.exists():  # (a real image is kept)
                image.touch()
