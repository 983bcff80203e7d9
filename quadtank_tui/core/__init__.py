"""The numeric core: plant models, analysis, signals and controllers.

Pure and deterministic: numbers in, numbers out.  Never imports textual, rich,
plotext or asyncio (tests/core/test_import_hygiene.py holds it to that).
"""
