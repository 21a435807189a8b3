"""The four source documents every system cites (``Model.source``), by title.

A system's ``source`` names its document by title (for the blog series: the title of the
post) and the section, as a reader would look it up: a chapter and section number where the
document numbers them (PHYS0500), a heading where it does not (the analytical-mechanics
notes), a topic and equation numbers for Lecture 10. ``docs/bibliography.md`` is written from
this table (``tools/readme_systems.py bibliography``). None of the documents is distributed
with mechsim, none names an author (PHYS0500's title page keeps a template placeholder), and
none gives a numerical parameter value: every default of every system is the project's choice.
Module docstrings and tests cite the same way: by title and section (a line number ``L<n>`` or
``line <n>`` is a position in the plain-text copy the project worked from, not a reference).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Document:
    """One source document: its title as printed, what kind of document it is, what it says
    of its author and of itself, and its sections (the titles a ``source`` cites)."""

    key: str
    title: str
    kind: str
    author: str
    notes: str
    sections: tuple[str, ...]

    def titles(self) -> tuple[str, ...]:
        """The titles a ``source`` may name: the blog series' post titles, else the title."""
        return self.sections if self.key == "posts" else (self.title,)


POSTS = Document(
    key="posts",
    title="Blog series on classical mechanics (ten posts; the page opens “Latest Posts”)",
    kind="blog posts, newest first; each post is cited by its own title",
    author="not given",
    notes=("The pendulum post credits Ted Jacobson's write-up on Lagrange multipliers; the "
           "general-theory post follows Spiegel, Theoretical Mechanics; the energy posts "
           "follow Goldstein, Classical Mechanics, ch. 1 and Morin. Figures are referred to "
           "but absent; the code is Python with SciPy's odeint."),
    sections=(
        "Dynamical Systems and Constraints: Part 3 – Simple Pendulum",
        "Dynamical Systems and Constraints: Part 2 – Bead on a Wire",
        "Dynamical Systems and Constraints: Part 1 – General Theory",
        "Energy and Hamiltonians: Part 3 – Examples",
        "Energy and Hamiltonians: Part 2 – Conservation Considerations",
        "Energy and Hamiltonians: Part 1 – Generalized Coordinates",
        "Action and Reaction",
        "Moving Frames and the Twisted Cubic",
        "Minimal Frames",
        "Relative Motion and Waves Redux",
    ))

ANALYTICAL = Document(
    key="analytical",
    title="Introduction to analytical mechanics",
    kind="lecture notes (slides as text), unnumbered headings",
    author="not given",
    notes=("Its reading list: Thornton & Marion; Kibble & Berkshire; Gregory; Morin; Greiner; "
           "Simmons; Goldstein; Lanczos; Callen. No Hamiltonian formalism, no rigid bodies, no "
           "rotating frames."),
    sections=(
        "Degrees of freedom", "Generalized coordinates", "Constraints",
        "Classification of constraints", "Conditions of balance",
        "Lagrange's equation of motion",
        "Atwood's machine – equation of motion Lagrangian", "Spring pendulum",
        "Double pendulum", "Lagrange's equation of motion velocity dependent potentials",
        "Lagrange's equation of motion with frictional forces", "Conservation theorems",
        "Conservation of energy", "Brachistochrone problem – shortest time problem",
        "calculus of variations", "Hamilton's principle",
        "Central force problem – with two body",
        "Two body problem equation – power law potentials", "Classification of the orbits",
        "Closed orbits of the two body problem", "Small Oscillations",
    ))

LECTURE10 = Document(
    key="lecture10",
    title="Lecture 10: The Methods of Lagrange Revisited",
    kind="lecture notes, Physics 229, Spring 2008 (equations numbered 10.1–10.67)",
    author="not given",
    notes=("Follows Kibble & Berkshire, Classical Mechanics, ch. 10, with its SI units for "
           "electromagnetism. Many symbols were lost in the text copy; the equation numbers "
           "cited are the notes' own."),
    sections=(
        "generalized coordinates and forces (eqs. 10.1–10.11)",
        "cylindrical and spherical coordinates, central force (eqs. 10.12–10.19)",
        "canonical momentum; linearly accelerated frame (eqs. 10.20–10.24)",
        "constraints and undetermined multipliers (eqs. 10.25–10.30)",
        "particle inside a vertical paraboloid (eqs. 10.31–10.36)",
        "Lagrange's heavy symmetric top (eqs. 10.37–10.46)",
        "spherical pendulum, free, with a vertical torque, or forced to rotate "
        "(eqs. 10.47–10.50)",
        "charged particle in an electromagnetic field, uniform B, gauge transformation "
        "(eqs. 10.51–10.67)",
    ))

PHYS0500 = Document(
    key="phys0500",
    title="PHYS0500 – Advanced Classical Mechanics",
    kind="course notes in eight numbered chapters",
    author="not given (the title page keeps a template placeholder)",
    notes="Follows Thornton & Marion. Figures 4.1–5.6 are referred to but absent.",
    sections=(
        "ch. 1 Oscillations (§1.1–1.7)", "ch. 2 Calculus of Variations (§2.1–2.5)",
        "ch. 3 Lagrangian and Hamiltonian Mechanics (§3.1–3.6)",
        "ch. 4 Central Force Motion (§4.1–4.6)", "ch. 5 Dynamics of Particle Systems (§5.1–5.3)",
        "ch. 6 Motion in Non-Inertial Reference Frames (§6.1–6.2)",
        "ch. 7 Dynamics of Rigid Bodies (§7.1–7.8)", "ch. 8 Coupled Oscillations (§8.1–8.4)",
    ))

DOCUMENTS = (POSTS, ANALYTICAL, LECTURE10, PHYS0500)


def documents_cited(source: str) -> list[Document]:
    """The documents a ``source`` text names (by a title they carry), in table order."""
    return [d for d in DOCUMENTS if any(t in source for t in d.titles())]
