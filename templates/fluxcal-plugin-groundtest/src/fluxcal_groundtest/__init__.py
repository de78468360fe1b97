"""Ground-test fluxgate: a fluxcal mission plugin (the template of docs/guide/plugins.md)."""
