"""Robot parameter files of climber_pkg (a package so that setup.py installs the YAML)."""
