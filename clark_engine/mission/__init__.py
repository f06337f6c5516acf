"""The mission language: load, validate, check and compile missions.

This package is the bottom layer of the engine: it imports nothing else of it.
Its entry points are :func:`clark_engine.mission.validate.validate_file` and
:func:`clark_engine.mission.compiler.compile_mission`.
"""
