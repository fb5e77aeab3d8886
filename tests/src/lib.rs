//! Workspace-level behaviour tests live in `tests/tests/`.
