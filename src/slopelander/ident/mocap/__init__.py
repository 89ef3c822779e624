"""Motion capture in: raw marker takes (C3D, Vicon Nexus CSV, OptiTrack Motive CSV, Qualisys
TSV) turned into drop recordings (docs/import.md).

One module per step: :mod:`.take` (a take's markers in metres, with gaps), :mod:`.formats`
(the readers), :mod:`.markerset` (the YAML that names the markers), :mod:`.pose` (the rigid
fit), :mod:`.plane` (the roof and the landing frame), :mod:`.contact` (first contact and the
impact state), :mod:`.rates` (the Savitzky-Golay rates), :mod:`.importer` (all of it, written
atomically). Nothing is imported here, so the recording format can use :mod:`.rates` alone.
"""
