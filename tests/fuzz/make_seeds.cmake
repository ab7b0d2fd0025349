# Seeds for the fuzzers, made rather than checked in: the shipped scenes and meshes, and a small
# bake's manifest.json and .vdb files (cmake -P, from the fuzz_seeds test).
file(REMOVE_RECURSE ${SEEDS})
file(MAKE_DIRECTORY ${SEEDS}/scene ${SEEDS}/obj ${SEEDS}/vdb_density ${SEEDS}/manifest ${SEEDS}/tmp)
# Each fuzzer's working corpus (what it finds besides the seeds), empty at every run.
foreach(target scene obj vdb_density manifest)
  file(MAKE_DIRECTORY ${SEEDS}/${target}-work)
endforeach()
file(GLOB scenes ${SOURCE}/configs/*.json ${SOURCE}/configs/report/*.json ${SOURCE}/tests/scenes/*.json)
file(COPY ${scenes} DESTINATION ${SEEDS}/scene)
file(COPY ${SOURCE}/configs/meshes/teapot.obj DESTINATION ${SEEDS}/obj)
file(WRITE ${SEEDS}/obj/small.obj "o leaves\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 -2 4\ng bark\nf 2/1 3/2 4/3\n")
file(WRITE ${SEEDS}/tmp/s.json [=[{"version": 1, "models": [{"name": "p", "density": {"type": "procedural", "shape": "plant",
  "resolution": 8}, "material": "leaf", "wood_material": "bark"}], "lighting": {"mode": "base", "solutions": "0,5"},
  "solver": {"iterations": 4}}]=])
execute_process(COMMAND ${LBLIGHT} bake ${SEEDS}/tmp/s.json -o ${SEEDS}/tmp/bake --backend cpu -q RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the seed bake failed (${rc})")
endif()
file(COPY ${SEEDS}/tmp/bake/manifest.json DESTINATION ${SEEDS}/manifest)
execute_process(COMMAND ${LBLIGHT} voxelize ${SEEDS}/obj/small.obj -r 6 -o ${SEEDS}/vdb_density/small.vdb -q RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the seed voxelisation failed (${rc})")
endif()
file(COPY ${SEEDS}/tmp/bake/p.vdb DESTINATION ${SEEDS}/vdb_density)
