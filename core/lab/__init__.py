"""The lab: tooling around the engine that does not ship in the extension.

Benchmarks, reports, the accuracy/speed trade-off, motion replays, batch jobs,
images and the command line (``python -m core ...``) live here. They import the
engine (``core``) and never the other way round; the extension zip leaves this
package out (``blender_manifest.toml`` ``paths_exclude_pattern``).
"""
