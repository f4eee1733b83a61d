"""An example drivenav plug-in package: the farthest-frontier explorer (:mod:`.config`, :mod:`.explorer`), the
embedded world seen through a noisy depth camera (:mod:`.world`, :mod:`.noisy_depth`) and a robot's sensor source and
motion executor for a bring-up without the robot (:mod:`.robot`, :mod:`.frames`), each declared by one entry point in
pyproject.toml."""
