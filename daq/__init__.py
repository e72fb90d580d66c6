"""beambench acquisition: device protocols, real drivers, fakes, anti-alias
filtering and decimation, and the MCAP run log. No physics, no image analysis;
imports neither ``sim`` nor ``vision``."""
