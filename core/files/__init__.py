"""The run directory: its layout, writer and readers, the GLB and PLY it writes, atomic writes,
image encodings (the plant file readers and the exports are plugins: agrisim.plugins.formats,
agrisim.plugins.exporters)."""
