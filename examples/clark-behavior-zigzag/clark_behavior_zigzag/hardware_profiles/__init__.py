"""Hardware profiles this plugin adds: the YAML files under this folder."""
