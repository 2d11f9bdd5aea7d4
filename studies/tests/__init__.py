"""The studies package's tests (a package, so that its conftest is ``tests.conftest`` beside the library's ``conftest``)."""
