"""agrisim's version, in a module of its own so that any module can name it without importing the
package's public façade."""

__version__ = "0.7.0"
