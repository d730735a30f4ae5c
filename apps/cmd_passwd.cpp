// `dronetrack passwd USERS_FILE USER [--delete]`: adds a user to the HTTP server's users file,
// or sets its password, or (--delete) revokes it. The password is read from the first line of
// stdin (so that it never appears in a process list or shell history); only a salted PBKDF2
// hash is written. Other lines and comments are kept as they are; the file is replaced
// atomically with mode 0600, and a running server picks the change up within a second.
#include <sys/stat.h>

#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "apps/commands.hpp"
#include "common/input_file.hpp"
#include "common/log.hpp"
#include "common/output_file.hpp"
#include "http_api/user_file.hpp"

namespace dronetrack::apps {
namespace {

struct PasswdArguments {
  std::string users_file;
  std::string user;
  bool remove = false;
};

int run(const PasswdArguments& arguments) {
  if (!http_api::valid_user_name(arguments.user)) {
    throw UserError("passwd: user name '" + arguments.user +
                    "' must be 1-64 letters, digits, '.', '_' or '-'");
  }
  std::string text;
  if (std::filesystem::exists(arguments.users_file)) {
    try {
      text = read_text_file(arguments.users_file, http_api::kMaxUserFileBytes, "users file");
    } catch (const std::runtime_error& error) {
      throw UserError(error.what());
    }
    http_api::UserFile::parse(text, arguments.users_file);  // refuse to rewrite a broken file
  }
  std::string new_line;
  if (!arguments.remove) {
    std::string password;
    std::getline(std::cin, password);
    if (!password.empty() && password.back() == '\r') password.pop_back();
    if (password.empty()) throw UserError("passwd: no password on stdin (first line)");
    new_line = http_api::make_user_line(arguments.user, password);
  }
  std::string out;
  bool found = false;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(arguments.user + ":", 0) == 0) {
      found = true;
      if (!new_line.empty()) out += new_line + "\n";
      continue;
    }
    out += line + "\n";
  }
  if (!found && arguments.remove) {
    throw UserError("passwd: no user '" + arguments.user + "' in " + arguments.users_file);
  }
  if (!found) out += new_line + "\n";
  OutputFile file(arguments.users_file);
  if (!file.in_place() && ::fchmod(file.descriptor(), 0600) != 0) {
    throw UserError("passwd: cannot make " + arguments.users_file + " private (chmod 600)");
  }
  file.write(out);
  file.commit();
  log::info("passwd: ",
            arguments.remove ? "removed"
            : found          ? "updated"
                             : "added",
            " user ", arguments.user, " in ", arguments.users_file);
  return 0;
}

}  // namespace

void register_passwd(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<PasswdArguments>();
  auto* command = root.add_subcommand(
      "passwd", "Add, change (password on stdin) or --delete a user of the HTTP server");
  command->add_option("users_file", arguments->users_file, "Users file (http.users_file)")
      ->required();
  command->add_option("user", arguments->user, "User name")->required();
  command->add_flag("--delete", arguments->remove, "Revoke the user");
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
