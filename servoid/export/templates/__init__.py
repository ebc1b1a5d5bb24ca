"""Templates of the export formats (package data: ``backlash_compensator.h``)."""
