"""Reading users' files: measurement files (:mod:`.measurement_files`), track files (:mod:`.track_files`)."""
