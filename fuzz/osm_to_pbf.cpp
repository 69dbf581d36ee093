// Seed helper for fuzz_osm_file: converts an OSM file to another format by suffix
// (e.g. .osm -> .osm.pbf), so PBF seeds are made at run time from ../shared/data.
#include <exception>
#include <iostream>
#include <osmium/io/any_input.hpp>
#include <osmium/io/any_output.hpp>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: osm_to_pbf IN.osm OUT.osm.pbf\n";
    return 2;
  }
  try {
    osmium::io::Reader reader{argv[1]};
    osmium::io::Header header = reader.header();
    osmium::io::Writer writer{argv[2], header, osmium::io::overwrite::allow};
    while (osmium::memory::Buffer buffer = reader.read()) writer(std::move(buffer));
    writer.close();
    reader.close();
  } catch (const std::exception& e) {
    std::cerr << "osm_to_pbf: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
