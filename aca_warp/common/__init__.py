"""Pieces shared by HF and LF: errors, argument types, files and provenance, checkpoints."""
