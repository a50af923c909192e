"""Plumbing every layer shares and none owns: atomic file output and command-line argument types."""
