"""The application: the command line, the Ray comparison, its table, progress display."""
