"""The live view of `armbench serve --web`: monitor (Modbus poll + plant), commands, web app."""
