# box study (SPEC.md): stages init -> runs -> ensemble -> fits -> figures.
# The rules land with the study; until then the study contributes no targets.
