"""Clark Engine: declarative behaviour engine for fleets of small unmanned vehicles.

A mission is one YAML file. The engine loads it (:mod:`clark_engine.mission`),
checks it before anything flies, and compiles one self-contained config per agent.
"""

__version__ = "0.1.0"
