"""Running worlds: sessions, playback, timed commands, rendering, headless GL and the interactive viewer."""
