"""The studies ``rlcompare reproduce`` runs: their records in :mod:`rlcompare.studies.registry`, their modules
imported only when run."""
