"""Exporters: a finished run directory in another tool's format (``agrisim export NAME RUN_DIR
[OUT]``, :class:`agrisim.interfaces.Exporter`). One module each, each its own entry point:
``nerfstudio`` (``transforms.json`` and plant masks), ``coco`` (instance masks as RLE) and
``rosbag`` (a ROS 2 bag in MCAP)."""
