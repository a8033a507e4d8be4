"""Helpers for testing backends: the contract every backend of a kind keeps (:mod:`.contracts`)."""
