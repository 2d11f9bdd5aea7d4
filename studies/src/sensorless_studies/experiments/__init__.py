"""Reproductions of the papers' studies: each module has run(out, quick, seed, console) -> dict
(:mod:`.psm_identification` has :func:`~.psm_identification.psm_identification_study`)."""
