"""Reading users' files: measurement files (:mod:`.measurement_files`), position files (:mod:`.track_files`: CSV,
DataFrames; GPX in :mod:`.gpx_files`, raw AIS NMEA in :mod:`.nmea_files`)."""
