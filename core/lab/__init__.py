"""The laboratory room around the cell: geometry and procedural textures."""
