"""The mission language: load, validate, check and compile missions.

It sits at the bottom of the engine with the behaviours, whose registry it reads (the
import rules are docs/architecture.md's "Import direction"). Its entry points are
:func:`clark_engine.mission.validate.validate_path` and
:func:`clark_engine.mission.compiler.compile_mission`.
"""
