"""The missions: each folder holds one instrument's readers, levels and products.

Each mission declares what it hands the generic code in one
`fluxcal.runs.contract.Mission` (its ``mission.py``), registered under the entry-point
group ``fluxcal.missions`` (`fluxcal.runs.registry`): commands, batch day task, run
options, demo parts, frame kernels, archived-product reader.
"""
