"""Experiments: thin scripts that write ``results/<name>/`` (CSV, config.json, figures)."""
