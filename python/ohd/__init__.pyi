import os
from typing import Any, Callable, Dict, Iterable, List, Mapping, NamedTuple, Optional, Sequence, Union

import numpy as np

from ._ohd import ConfigError as ConfigError
from ._ohd import Experiment as Experiment

__version__: str
DEFAULT_CONFIG: str

Path = Union[str, os.PathLike[str]]
Config = Union[None, str, os.PathLike[str], Mapping[str, Any], Experiment]
Overrides = Union[None, Mapping[str, Any], Sequence[str]]
Report = Callable[[int, int], Any]

class Estimate(NamedTuple):
    value: float
    stderr: float

class Output:
    name: str
    values: np.ndarray
    stderr: Optional[np.ndarray]
    axes: Dict[str, np.ndarray]
    units: Optional[str]
    kind: Optional[str]
    def __array__(self, dtype: Any = ..., copy: Any = ...) -> np.ndarray: ...

class Result:
    files: Dict[str, bytes]
    manifest: Dict[str, Any]
    estimates: Dict[str, Any]
    pointings: List[Result]
    @property
    def outputs(self) -> Dict[str, Output]: ...
    def __getitem__(self, name: str) -> Output: ...
    def __contains__(self, name: str) -> bool: ...
    def save(self, dir: Path) -> None: ...
    def main_figure(self) -> Optional[bytes]: ...
    def _repr_html_(self) -> str: ...

def load(dir: Path) -> Result: ...
def check(config: Config = ..., *, overrides: Overrides = ...) -> Experiment: ...
def run(
    config: Config = ...,
    *,
    samples: Union[None, int, float] = ...,
    seed: Optional[int] = ...,
    threads: Optional[int] = ...,
    overrides: Overrides = ...,
    out: Optional[Path] = ...,
    progress: Union[bool, Report] = ...,
    figures: bool = ...,
    grids: Optional[Mapping[str, Any]] = ...,
) -> Result: ...
def sweep(
    config: Config,
    key: Optional[str] = ...,
    values: Optional[Iterable[Any]] = ...,
    *,
    points: Optional[Iterable[Overrides]] = ...,
    samples: Union[None, int, float] = ...,
    seed: Optional[int] = ...,
    threads: Optional[int] = ...,
    overrides: Overrides = ...,
    progress: Union[bool, Report] = ...,
    figures: bool = ...,
) -> List[Result]: ...
def mie(
    *,
    m_real: Optional[float] = ...,
    m_imag: float = ...,
    x: Optional[float] = ...,
    diameter_um: Optional[float] = ...,
    n_particle: Optional[float] = ...,
    k_particle: float = ...,
    n_medium: Optional[float] = ...,
    wavelength_nm: Optional[float] = ...,
    angles: Optional[int] = ...,
) -> Dict[str, Any]: ...
def converge(
    config: Optional[Path] = ...,
    *,
    out: Path,
    reference: Optional[Path] = ...,
    budget_seconds: float = ...,
    samples: Union[None, int, float] = ...,
    rungs: int = ...,
    overrides: Overrides = ...,
    seed: Optional[int] = ...,
    threads: Optional[int] = ...,
    figures: bool = ...,
) -> Dict[str, Any]: ...
