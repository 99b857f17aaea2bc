"""Seas for the ROM (issue 11): spectra, spreading, components, the Sea interface, sea-state table, wave-load grid.

Direction convention everywhere: the direction the waves travel towards, native earth frame, 0 = +x_E
(the authors' waves), 90 = +y_E; degrees at the edges, radians inside.
"""
from .components import WaveComponents, discretise, read_components_csv, regular_components, write_components_csv
from .errors import SeaInputError
from .sea import AuthorsTableSea, ComponentSea, Sea, calm_sea
from .sea_states import sea_state_hs_tp
from .spectra import (BretschneiderSpectrum, ITTCSpectrum, JonswapSpectrum, PiersonMoskowitzSpectrum,
                      spectrum)
from .spreading import Cos2sSpreading

__all__ = ["WaveComponents", "discretise", "read_components_csv", "regular_components", "write_components_csv",
           "SeaInputError", "AuthorsTableSea", "ComponentSea", "Sea", "calm_sea", "sea_state_hs_tp",
           "BretschneiderSpectrum", "ITTCSpectrum", "JonswapSpectrum", "PiersonMoskowitzSpectrum", "spectrum",
           "Cos2sSpreading"]
