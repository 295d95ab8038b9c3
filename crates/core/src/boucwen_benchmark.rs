//! The Bouc–Wen hysteretic benchmark system (Noël & Schoukens 2016), SPEC §3.3.
