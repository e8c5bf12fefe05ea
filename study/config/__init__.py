"""What a study compares, before anything is computed:

  techniques   a column: label, technique (registry, entry point or the user's file) and parameters
  protocols    the static and ghosting tests as schedules of steps, and the raster frames they need
  profile      a whole study (scenes, techniques, protocols, settings) and the thesis's columns
  studyfile    TOML study files (the built-in profiles/*.toml are such files)
  defaults     every default of the above, in one place
"""
