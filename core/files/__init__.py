"""File formats and the run directory: plant assets (glTF, OBJ), the GLB writer, atomic writes, image encodings, run-directory readers and exports."""
