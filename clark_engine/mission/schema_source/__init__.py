"""The source of the JSON Schemas in ``schemas/``.

The schemas are written as Python data so that parts can be shared (points,
channel maps) and so that the mission schema is built from the primitives'
own parameter declarations (one module per primitive, registry builds the
schema). ``python -m clark_engine.mission.schema_source`` writes them to
``schemas/``; a test fails when the files and this source drift apart.
"""
