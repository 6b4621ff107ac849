"""The ``fluidnexus`` command line: thin click commands (parse -> load -> call the library -> save)."""
