"""``fluidnexus batch``: the pipeline over many scenes as Ray tasks (docs/batch.md).

- :mod:`.manifest` reads and checks the manifest (TOML or JSON) into :class:`~.manifest.SceneJob` entries.
- :mod:`.steps` turns one step of one scene into the arguments of the single-scene command that does it.
- :mod:`.tasks` runs one step in a Ray worker (shared-storage check, resume, completion marker).
- :mod:`.runner` starts or joins Ray and drives the steps: in order per scene, scenes in parallel.
- :mod:`.results` writes results.csv, results.md, results.png and batch.json.

Ray is imported only by :mod:`.runner` (the ``cluster`` extra); the rest works without it.
"""
