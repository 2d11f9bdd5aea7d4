"""Reproductions of the papers' studies: each module has run(out, quick, seed, console) -> dict."""
