"""The application's jobs: one module per job, shared by the command line and the web API."""
