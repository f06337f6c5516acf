"""Behaviour blocks this plugin adds: the YAML files in this folder."""
