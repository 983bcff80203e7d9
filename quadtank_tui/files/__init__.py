"""Files: `.par` parameters, `.log` data and their exports.

This layer may import the core, never textual, asyncio, the engine or the UI.
"""
